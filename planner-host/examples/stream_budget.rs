//! The size of the streamed plan: each curve planned with
//! `PlanConfig::default()`, its table cut into chunks (chunk format
//! version 2, `firmware_core::stream`) by `planner_host::stream`, decoded
//! again and compared with the table word for word, and its bytes per mm
//! of path printed, with and without the f32 u form, chunks alone and in
//! DATA frames on the link (COBS and delimiter).
//!
//!     cargo run --release -p planner-host --example stream_budget -- [--chunk-mm MM] [--max-bytes N] [--link FILE] [--digest] [CURVE ...]
//!
//! CURVE is a built-in name (butterfly, circle, fan, star, trident) or a
//! curve JSON file; without one, all five built-in curves. `--chunk-mm`:
//! chunk length (default 32). `--max-bytes N`: halve longer chunks until
//! they fit N bytes (`ChunkOptions::max_chunk_bytes`). `--link FILE`: also write the first curve's
//! stream (u form, framed) to FILE, e.g. as a fuzz seed or for the MCU
//! (`firmware-core/mcu`, bin `stream-decode`); `--digest`: print each
//! curve's decode digest (u form; `Fnv1a64::chunk` over every chunk in
//! order), the number the MCU's `stream-decode` prints for the same stream.

use std::path::Path;

use firmware_core::Table;
use planner_host::stream::{
    chunk_table, decode_chunks, first_difference, ChunkOptions, StreamSize, TableRows,
};
use planner_host::{builtin, cli, plan_curve, PlanConfig};

fn main() {
    let mut args = std::env::args().skip(1);
    let mut chunk_mm = 32.0;
    let mut link: Option<String> = None;
    let mut digest = false;
    let mut max_bytes: Option<usize> = None;
    let mut curves = vec![];
    while let Some(a) = args.next() {
        match a.as_str() {
            "--chunk-mm" => chunk_mm = args.next().and_then(|v| v.parse().ok()).expect("--chunk-mm MM"),
            "--link" => link = Some(args.next().expect("--link FILE")),
            "--digest" => digest = true,
            "--max-bytes" => {
                max_bytes = Some(args.next().and_then(|v| v.parse().ok()).expect("--max-bytes N"))
            }
            _ => curves.push(a),
        }
    }
    if curves.is_empty() {
        curves = builtin::NAMES.iter().map(|s| s.to_string()).collect();
    }
    println!("chunks of {chunk_mm} mm; B/mm of path: chunks, framed on the link, of the chunks the q parts and the pieces\n");
    println!("| curve | L mm | pieces (/mm) | chunks | table | u form: chunks | framed | q | pieces | no u form: chunks | framed | q | pieces |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for (k, arg) in curves.iter().enumerate() {
        let curve = cli::load_curve(Path::new(arg)).unwrap_or_else(|e| panic!("{arg}: {e}"));
        let out = plan_curve(&curve, &PlanConfig::default()).unwrap_or_else(|e| panic!("{arg}: {e}"));
        let table = Table::parse(&out.table_bytes).expect("the planner's table parses");
        let rows = TableRows::of(&table);
        let len = table.path_length_mm();
        let mut cells = vec![];
        let mut n_chunks = 0;
        for u_form in [true, false] {
            let opts = ChunkOptions {
                chunk_mm,
                u_form,
                max_chunk_bytes: max_bytes,
                ..ChunkOptions::default()
            };
            let chunks = chunk_table(&table, &opts).expect("the table cuts into chunks");
            let decoded = decode_chunks(&chunks).expect("the chunks decode");
            if let Some(d) = first_difference(&rows, &decoded, u_form) {
                panic!("{arg}: round trip differs: {d}");
            }
            let s = StreamSize::of(&chunks);
            n_chunks = s.chunks;
            cells.push(format!(
                "{:.1} | {:.1} | {:.1} | {:.1}",
                s.chunk_bytes as f64 / len,
                s.framed_bytes as f64 / len,
                s.q_bytes as f64 / len,
                s.piece_bytes as f64 / len
            ));
            if u_form && digest {
                let mut d = firmware_core::digest::Fnv1a64::new();
                for c in &chunks {
                    d.chunk(&firmware_core::stream::Chunk::parse(c).expect("the chunk parses"));
                }
                println!("{}: decode digest 0x{:016x}", out.curve, d.finish());
            }
            if u_form && k == 0 {
                if let Some(path) = &link {
                    let mut bytes = vec![];
                    for c in &chunks {
                        let mut f = vec![0u8; c.len() * 2 + 8];
                        let n = firmware_core::stream::frame::encode_data(c, &mut f).expect("frame");
                        bytes.extend_from_slice(&f[..n]);
                    }
                    std::fs::write(path, bytes).unwrap_or_else(|e| panic!("{path}: {e}"));
                }
            }
        }
        let n_pieces = rows.breaks.len().saturating_sub(1);
        println!(
            "| {} | {len:.2} | {n_pieces} ({:.3}) | {n_chunks} | {:.1} | {} | {} |",
            out.curve,
            n_pieces as f64 / len,
            out.table_bytes.len() as f64 / len,
            cells[0],
            cells[1]
        );
    }
}
