//! Where the bytes of a firmware table go, per mm of path: the measurement
//! behind `docs/streaming-design.md`.
//!
//! Plans each curve with `PlanConfig::default()`, parses the encoded table
//! with firmware-core's [`Table::parse`] (so every size printed is of a
//! table the firmware accepts), walks the section directory (the byte
//! layout in `firmware_core::table`) and prints, per section and per group
//! of sections: element count, bytes, bytes per mm, the share of the table,
//! and the link rate needed to stream that section at full feed (v̄ =
//! 166.67 mm/s, TABLE1) in bytes/s and in baud at 10 bits a byte (8N1).
//! Then the items per mm (s → u segments, position pieces, q spans, NURBS
//! control points and knots), the pieces' lengths, and how many bits the
//! fixed-point position coefficients actually use (the room a compact
//! encoding has).
//!
//!     cargo run --release -p planner-host --example table_budget -- [--prototype] [CURVE ...]
//!
//! CURVE is a built-in name (butterfly, circle, fan, star, trident) or a
//! curve JSON file; without one, the Butterfly.
//!
//! `--prototype` adds the measurement of the PROTOTYPE compact chunk
//! encoding (module `compact`): the table's pieces encoded losslessly, and
//! longer pieces re-fitted across s → u segments (degree 7, and 9 and 11 for
//! comparison), each encoded, decoded and compared, in bytes per mm with
//! the q spans and the chunk framing;
//! `--fit-tol MM` the same with another fit tolerance for the re-fitted
//! pieces (default 2e-11 mm, the table's tolerance when the prototype was
//! written; the table's pieces are now fitted this way at 1e-10 mm,
//! `firmware_core` `servo_forms::fit`).

mod compact;

use std::path::Path;

use firmware_core::math::source::Point4Array;
use firmware_core::table::layout::{CRC_LEN, DIR_ENTRY_LEN};
use firmware_core::table::Section;
use firmware_core::{F64Array, Table};
use planner_host::{cli, plan_curve, ArcLength, PlanConfig};

/// Full feed of TABLE1, mm/s.
const FULL_FEED_MM_S: f64 = 166.67;
/// Line bits per byte on an 8N1 serial link.
const BITS_PER_BYTE: f64 = 10.0;
/// 64-bit words per piece in section 12: u_a, centre, shift/mask, 3 × 8 b_k.
const PIECE_WORDS: usize = 27;
/// Position coefficients per axis.
const POS_COEFFS: usize = 8;

/// One directory entry of the table.
struct Entry {
    kind: u16,
    count: u32,
    offset: u32,
    byte_len: u32,
}

fn u16_at(b: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([b[at], b[at + 1]])
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// The directory (header: header length u16 at 6, section count u16 at 12;
/// entries: kind u16 at 0, count u32 at 4, offset u32 at 8, byte length
/// u32 at 12), of a table that [`Table::parse`] accepted.
fn directory(b: &[u8]) -> (usize, Vec<Entry>) {
    let header_len = usize::from(u16_at(b, 6));
    let n = usize::from(u16_at(b, 12));
    let entries = (0..n)
        .map(|i| {
            let e = header_len + i * DIR_ENTRY_LEN;
            Entry {
                kind: u16_at(b, e),
                count: u32_at(b, e + 4),
                offset: u32_at(b, e + 8),
                byte_len: u32_at(b, e + 12),
            }
        })
        .collect();
    (header_len, entries)
}

fn name(kind: u16) -> String {
    match Section::from_code(kind) {
        Some(s) => format!("{s:?}"),
        None => format!("extension {kind:#06x}"),
    }
}

/// The group a section belongs to in the summary.
fn group(kind: u16) -> &'static str {
    match kind {
        1 | 2 => "limits + meta",
        3 | 4 => "NURBS",
        5..=7 => "s→u map",
        8 | 9 | 10 | 14 | 15 => "q",
        11..=13 => "position pieces",
        16..=19 => "override levels",
        _ => "extensions",
    }
}

const GROUPS: [&str; 8] = [
    "limits + meta",
    "NURBS",
    "s→u map",
    "q",
    "position pieces",
    "override levels",
    "extensions",
    "framing (header, directory, padding, CRC)",
];

/// Bits of a two's-complement integer holding `v` (sign included).
fn signed_bits(v: i64) -> u32 {
    if v >= 0 {
        65 - v.leading_zeros()
    } else {
        65 - (!v).leading_zeros()
    }
}

fn row(label: &str, count: String, bytes: usize, len: f64, total: usize) {
    let per_mm = bytes as f64 / len;
    let rate = per_mm * FULL_FEED_MM_S;
    println!(
        "| {label} | {count} | {bytes} | {per_mm:.1} | {:.1} % | {rate:.0} | {:.0} |",
        100.0 * bytes as f64 / total as f64,
        rate * BITS_PER_BYTE
    );
}

fn quantile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    sorted[((sorted.len() - 1) as f64 * q).round() as usize]
}

fn report(arg: &str, prototype: Option<f64>) -> Result<(), String> {
    let curve = cli::load_curve(Path::new(arg)).map_err(|e| format!("{arg}: {e}"))?;
    let out = plan_curve(&curve, &PlanConfig::default()).map_err(|e| format!("{arg}: {e}"))?;
    let bytes = &out.table_bytes;
    let table = Table::parse(bytes).map_err(|e| format!("{arg}: table refused: {e}"))?;
    let len = table.path_length_mm();
    let total = bytes.len();
    let (header_len, dir) = directory(bytes);

    println!("## {} (`{arg}`)\n", out.curve);
    println!(
        "L = {len:.3} mm, predicted T = {:.3} s, table {total} bytes = {:.1} bytes/mm; \
         streamed at full feed {FULL_FEED_MM_S} mm/s: {:.0} bytes/s = {:.0} baud (8N1); \
         over the planned time (mean feed {:.1} mm/s): {:.0} bytes/s\n",
        table.predicted_time_s(),
        total as f64 / len,
        total as f64 / len * FULL_FEED_MM_S,
        total as f64 / len * FULL_FEED_MM_S * BITS_PER_BYTE,
        len / table.predicted_time_s(),
        total as f64 / table.predicted_time_s(),
    );

    println!("| section | elements | bytes | bytes/mm | share | bytes/s at full feed | baud |");
    println!("|---|---|---|---|---|---|---|");
    let mut group_bytes = vec![0usize; GROUPS.len()];
    let mut payload = 0usize;
    for e in &dir {
        let g = GROUPS.iter().position(|&n| n == group(e.kind)).unwrap_or(6);
        group_bytes[g] += e.byte_len as usize;
        payload += e.byte_len as usize;
        row(
            &format!("{} ({}) @{}", name(e.kind), e.kind, e.offset),
            e.count.to_string(),
            e.byte_len as usize,
            len,
            total,
        );
    }
    let framing = total - payload;
    group_bytes[GROUPS.len() - 1] = framing;
    row(
        &format!(
            "header {header_len} + directory {} + padding + CRC {CRC_LEN}",
            dir.len() * DIR_ENTRY_LEN
        ),
        "-".into(),
        framing,
        len,
        total,
    );
    row("**whole table**", "-".into(), total, len, total);
    println!();
    println!("| group | bytes | bytes/mm | share | bytes/s at full feed | baud |");
    println!("|---|---|---|---|---|---|");
    for (g, &b) in GROUPS.iter().zip(&group_bytes) {
        if b > 0 {
            let per_mm = b as f64 / len;
            println!(
                "| {g} | {b} | {per_mm:.1} | {:.1} % | {:.0} | {:.0} |",
                100.0 * b as f64 / total as f64,
                per_mm * FULL_FEED_MM_S,
                per_mm * FULL_FEED_MM_S * BITS_PER_BYTE
            );
        }
    }

    // Items.
    let pieces = table.piece_breaks().len().saturating_sub(1);
    let q_spans = table.q_local().len() / 5;
    let su = table.su_breaks().len().saturating_sub(1);
    let n_pts = table.nurbs_points().len();
    let n_knots = table.nurbs_knots().len();
    let q_ctrl = table.q_ctrl().len();
    println!();
    println!("| item | count | per mm | mean length, mm | table bytes each |");
    println!("|---|---|---|---|---|");
    let item = |what: &str, n: usize, each: f64| {
        println!(
            "| {what} | {n} | {:.3} | {:.3} | {each:.1} |",
            n as f64 / len,
            len / n as f64
        );
    };
    item(
        "position pieces (11–13)",
        pieces,
        (8 + 8 * PIECE_WORDS + 28) as f64,
    );
    item(
        "q spans (10, 15; knot and ctrl 8, 9)",
        q_spans,
        (20 + 40 + 8 + 8) as f64,
    );
    item("q control points (9)", q_ctrl, 8.0);
    item("s→u segments (5–7)", su, (8 + 4 + 48) as f64);
    item("NURBS control points (4)", n_pts, 32.0);
    item("NURBS knots (3)", n_knots, 8.0);

    // Piece lengths and coefficient widths.
    let breaks: Vec<f64> = table.piece_breaks().iter().collect();
    let mut lens: Vec<f64> = breaks.windows(2).map(|w| w[1] - w[0]).collect();
    lens.sort_by(f64::total_cmp);
    let words = table.piece_f64();
    let mut width = [[0u32; POS_COEFFS]; 3];
    let mut const_axes = [0usize; 3];
    let mut centre_delta_bits = 0u32;
    let mut prev_centre: Option<i64> = None;
    for p in 0..pieces {
        let w = |i: usize| words.get_i64(p * PIECE_WORDS + i).unwrap_or(0);
        let centre = w(1);
        if let Some(c) = prev_centre {
            centre_delta_bits = centre_delta_bits.max(signed_bits(centre - c));
        }
        prev_centre = Some(centre);
        let mask = (w(2) >> 8) & 7;
        for (a, (wa, ca)) in width.iter_mut().zip(const_axes.iter_mut()).enumerate() {
            if mask & (1 << a) != 0 {
                *ca += 1;
            }
            for (k, wk) in wa.iter_mut().enumerate() {
                *wk = (*wk).max(signed_bits(w(3 + a * POS_COEFFS + k)));
            }
        }
    }
    println!();
    println!(
        "piece length, mm: min {:.4}, 10 % {:.3}, median {:.3}, 90 % {:.3}, max {:.3}; \
         constant axes (x, y, z): {:?} of {pieces} pieces",
        quantile(&lens, 0.0),
        quantile(&lens, 0.1),
        quantile(&lens, 0.5),
        quantile(&lens, 0.9),
        quantile(&lens, 1.0),
        const_axes
    );
    println!(
        "bits used by the Q40 position coefficients b_k (max over pieces, sign included), \
         k = 0..7: x {:?}, y {:?}, z {:?}; centre − previous centre: {centre_delta_bits} bits\n",
        width[0], width[1], width[2]
    );
    if let Some(fit_tol) = prototype {
        prototype_report(&curve, &table, len, fit_tol);
    }
    Ok(())
}

/// One set of pieces encoded, decoded and compared.
struct Variant {
    label: &'static str,
    n: usize,
    median_mm: f64,
    e: compact::Encoded,
}

fn variant<const C: usize>(
    label: &'static str,
    pieces: &[compact::Piece<C>],
    q_knots: &[f64],
    how: (compact::Breaks, usize),
) -> Variant {
    let mut lens: Vec<f64> = pieces.iter().map(|p| p.len_mm()).collect();
    lens.sort_by(f64::total_cmp);
    Variant {
        label,
        n: pieces.len(),
        median_mm: quantile(&lens, 0.5),
        e: compact::encode_chunks(pieces, q_knots, how),
    }
}

/// The PROTOTYPE compact encoding on this curve (see [`compact`]).
fn prototype_report(curve: &planner_host::Nurbs, table: &Table, len: f64, fit_tol: f64) {
    use compact::{Breaks, CHUNK_MM, HEADER_LEN, U_FORM_LEN};
    let q_knots: Vec<f64> = table.q_knots().iter().collect();
    let ours = compact::table_pieces(table);
    let arc = ArcLength::new(curve);
    let refit = compact::refit::<8>(curve, &arc, table, fit_tol);
    let refit9 = compact::refit::<10>(curve, &arc, table, fit_tol);
    let refit11 = compact::refit::<12>(curve, &arc, table, fit_tol);
    println!(
        "PROTOTYPE compact encoding: chunks of {CHUNK_MM} mm, header {HEADER_LEN} + CRC 4 + COBS; \
         q spans as h (Q20 LEB128) + f64 ctrl, 3 spans repeated a chunk; u form not sent \
         (with it: + {U_FORM_LEN} bytes a piece)\n"
    );
    println!(
        "| pieces | count | per mm | median length mm | piece B/mm | B/piece | q B/mm | framing B/mm | \
         **total B/mm** | + u form | round trip |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    let mut rates = Vec::new();
    let variants = [
        variant("table's, lossless", &ours, &q_knots, (Breaks::Table, 0)),
        variant(
            "re-fitted across s→u segments, Q20 breaks",
            &refit.pieces,
            &q_knots,
            (Breaks::Grid, 0),
        ),
        variant(
            "re-fitted, b₁ b₂ predicted at the join",
            &refit.pieces,
            &q_knots,
            (Breaks::Grid, 2),
        ),
        variant(
            "re-fitted, b₁ b₂ b₃ predicted at the join",
            &refit.pieces,
            &q_knots,
            (Breaks::Grid, 3),
        ),
        variant(
            "re-fitted at degree 9, b₁ b₂ b₃ predicted",
            &refit9.pieces,
            &q_knots,
            (Breaks::Grid, 3),
        ),
        variant(
            "re-fitted at degree 11, b₁ b₂ b₃ predicted",
            &refit11.pieces,
            &q_knots,
            (Breaks::Grid, 3),
        ),
    ];
    for v in variants.iter() {
        let (e, n) = (&v.e, v.n);
        let total = e.piece_bytes + e.q_bytes + e.frame_bytes;
        rates.push((v.label, total as f64 / table.predicted_time_s(), &e.at));
        println!(
            "| {} | {n} | {:.3} | {:.3} | {:.1} | {:.1} | {:.1} | {:.1} | **{:.1}** | {:.1} | {} of {n} pieces differ |",
            v.label,
            n as f64 / len,
            v.median_mm,
            e.piece_bytes as f64 / len,
            e.piece_bytes as f64 / n as f64,
            e.q_bytes as f64 / len,
            e.frame_bytes as f64 / len,
            total as f64 / len,
            (total + U_FORM_LEN * n) as f64 / len,
            e.mismatches
        );
    }
    println!(
        "\nlink rate of the streams over the planned motion (bytes/s; worst window of 0.25 s / 1 s / 4 s):\n"
    );
    println!("| pieces | mean over T | 0.25 s | 1 s | 4 s | full feed × B/mm |");
    println!("|---|---|---|---|---|---|");
    for (label, mean, at) in &rates {
        let total: usize = at.iter().map(|a| a.1).sum();
        println!(
            "| {label} | {mean:.0} | {:.0} | {:.0} | {:.0} | {:.0} |",
            compact::peak_rate(table, at, 0.25),
            compact::peak_rate(table, at, 1.0),
            compact::peak_rate(table, at, 4.0),
            total as f64 / len * FULL_FEED_MM_S
        );
    }
    let q_ctrl: Vec<f64> = table.q_ctrl().iter().collect();
    let [q64, q32, qd] = compact::q_sizes(&q_knots, &q_ctrl, 8);
    println!(
        "\nq spans alone (h in Q20 + one ctrl a span, without the chunk context): f64 ctrl {:.1} B/mm, \
         f32 ctrl {:.1} B/mm, ctrl deltas on a 2^-8 (mm/s)² grid {:.1} B/mm",
        q64 as f64 / len,
        q32 as f64 / len,
        qd as f64 / len
    );
    println!();
    let fits = [
        (
            7,
            refit.max_fit_err,
            refit.over_tol,
            compact::compare(&refit.pieces, &ours, 9),
        ),
        (
            9,
            refit9.max_fit_err,
            refit9.over_tol,
            compact::compare(&refit9.pieces, &ours, 9),
        ),
        (
            11,
            refit11.max_fit_err,
            refit11.over_tol,
            compact::compare(&refit11.pieces, &ours, 9),
        ),
    ];
    for (deg, err, over, (diff, step)) in fits {
        println!(
            "re-fitted pieces, degree {deg} (tolerance {fit_tol:e} mm): largest |piece − r(s)| at the {} check points \
             {err:.2e} mm ({over} pieces over the tolerance after 10 bisections); largest |re-fitted − table's pieces| \
             {diff:.2e} mm (9 points a piece; includes the table's s → u map error, ≤ 1e-6 mm in s); \
             largest step between re-fitted pieces {step} Q40 units ({:.1e} mm)",
            4 * deg + 1,
            step as f64 / (1u64 << 40) as f64
        );
    }
    println!();
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.iter().any(|a| a == "-h" || a == "--help") {
        println!("usage: table_budget [--prototype | --fit-tol MM] [CURVE ...]   (built-in name or curve JSON; default butterfly)");
        return;
    }
    let all = args.join(" ");
    let mut prototype = None;
    let mut rest = Vec::new();
    let mut it = args.into_iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--prototype" => prototype = prototype.or(Some(compact::FIT_TOL_MM)),
            "--fit-tol" => prototype = it.next().and_then(|x| x.parse().ok()),
            _ => rest.push(a),
        }
    }
    let mut args = rest;
    if args.is_empty() {
        args.push("butterfly".into());
    }
    println!("command: cargo run --release -p planner-host --example table_budget -- {all}\n");
    for a in &args {
        if let Err(e) = report(a, prototype) {
            eprintln!("table_budget: {e}");
            std::process::exit(1);
        }
    }
}
