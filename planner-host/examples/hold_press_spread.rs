//! How far a starved stop's rest point moves when the hold is pressed a
//! tick or two after its hold point, or between the search's ticks: the
//! spread the hold points' margin must cover (`planner_host::stream_hold`,
//! the ticks after s_c and the margin's fraction).
//!
//! The curve is planned whole, cut into chunks and given hold points for
//! a firmware window of Q q spans and P pieces (`set_hold_points`). Then
//! the firmware's streamed interpolator runs the plan as the search's dry
//! run does, every chunk arriving in time, and at its first tick at or
//! past each chunk's hold point s_c and at each of the `--ticks` − 1
//! ticks after it, a copy of the run is cut back to the chunk's end, the
//! hold pressed and ticked to rest (`presses_near_hold_points`). At the
//! search's own servo period the first press is the search's test at s_c;
//! at one a little off it (`--run-period-us 250.0001`) the ticks slide
//! between the search's, where a firmware's fall after a starvation.
//!
//!     cargo run --release -p planner-host --example hold_press_spread -- [--window-rows 128:256|256:512] [--chunk-mm MM] [--ticks N] [--run-period-us US] [--press-ticks N] [--margin-frac F] [--each] [CURVE]
//!
//! CURVE is a built-in name (butterfly, circle, fan, star, trident) or a
//! curve JSON file (default: `curves/long/meander-11m.json`); the window
//! 128:256 by default, chunks of 8 mm, 3 ticks, the search's period.
//! `--press-ticks` and `--margin-frac`: the search's
//! (`HoldSearch::press_ticks`, `HoldSearch::margin_frac`; default the
//! search's defaults). Per chunk (`--each`): where the first press was,
//! its stop and the room its rest left before the chunk's end, and the
//! furthest rest of the presses after it. Then, over the chunks: how much
//! further than the first press the furthest of them rested, in mm and as
//! a fraction of the stop, and at how many hold points a press ran past
//! the chunk's end (the tick faulting there) or left less room than the
//! search's margins.

use std::path::Path;

use firmware_core::Table;
use planner_host::stream::{chunk_table, ChunkOptions};
use planner_host::stream_hold::{on_big_stack, presses_near_hold_points, set_hold_points, HoldSearch};
use planner_host::{builtin, cli, plan_curve, PlanConfig};

struct Args {
    rows: (usize, usize),
    chunk_mm: f64,
    ticks: usize,
    each: bool,
    curve: String,
    how: HoldSearch,
    run_period_s: f64,
}

fn main() {
    let mut a = Args {
        rows: (128, 256),
        chunk_mm: 8.0,
        ticks: 3,
        each: false,
        how: HoldSearch::default(),
        run_period_s: HoldSearch::default().period_s,
        curve: format!("{}/curves/long/meander-11m.json", env!("CARGO_MANIFEST_DIR")),
    };
    let mut args = std::env::args().skip(1);
    while let Some(x) = args.next() {
        match x.as_str() {
            "--window-rows" => {
                let v = args.next().expect("--window-rows Q:P");
                let (q, p) = v.split_once(':').expect("--window-rows Q:P");
                a.rows = (q.parse().expect("Q"), p.parse().expect("P"));
            }
            "--chunk-mm" => a.chunk_mm = args.next().and_then(|v| v.parse().ok()).expect("--chunk-mm MM"),
            "--ticks" => a.ticks = args.next().and_then(|v| v.parse().ok()).expect("--ticks N"),
            "--each" => a.each = true,
            "--press-ticks" => {
                a.how.press_ticks = args.next().and_then(|v| v.parse().ok()).expect("--press-ticks N")
            }
            "--margin-frac" => {
                a.how.margin_frac = args.next().and_then(|v| v.parse().ok()).expect("--margin-frac F")
            }
            "--run-period-us" => {
                a.run_period_s = args
                    .next()
                    .and_then(|v| v.parse::<f64>().ok())
                    .expect("--run-period-us US")
                    * 1e-6
            }
            c => a.curve = c.to_string(),
        }
    }
    let run = match a.rows {
        (128, 256) => on_big_stack(|| spread::<128, 256>(&a)),
        (256, 512) => on_big_stack(|| spread::<256, 512>(&a)),
        r => panic!("window {r:?}: 128:256 or 256:512"),
    };
    run.expect("the run's thread failed");
}

fn spread<const Q: usize, const P: usize>(a: &Args) {
    let curve = match builtin::by_name(&a.curve) {
        Some(Ok(c)) => c,
        _ => cli::load_curve(Path::new(&a.curve)).expect("a curve JSON"),
    };
    let out = plan_curve(&curve, &PlanConfig::default()).expect("the plan");
    let table = Table::parse(&out.table_bytes).expect("its table");
    let opts = ChunkOptions {
        chunk_mm: a.chunk_mm,
        u_form: true,
        ..ChunkOptions::default()
    };
    let mut chunks = chunk_table(&table, &opts).expect("the chunks");
    let how = a.how;
    let hp = set_hold_points::<Q, P>(&table, &mut chunks, &how).expect("the hold points");
    let near = presses_near_hold_points::<Q, P>(&table, &chunks, &hp.s_c_mm, a.run_period_s, a.ticks)
        .expect("the presses");
    println!(
        "{}: {} chunks of {} mm, window {}:{}, {} hold points (presses tested {}), presses at the first tick at or past s_c and the {} after it, ticks of {} µs",
        a.curve,
        chunks.len(),
        a.chunk_mm,
        Q,
        P,
        near.len(),
        how.press_ticks,
        a.ticks.saturating_sub(1),
        a.run_period_s * 1e6
    );
    let (mut more, mut frac, mut past, mut short) = (vec![], vec![], 0usize, 0usize);
    for n in &near {
        let Some(&(press, rest0)) = n.presses.first() else {
            continue;
        };
        let later = n.presses[1..]
            .iter()
            .map(|p| p.1)
            .fold(f64::NEG_INFINITY, f64::max);
        let worst = rest0.max(later);
        let stop = rest0 - press;
        if worst >= n.end_mm {
            past += 1;
        } else if n.end_mm - worst < how.margin_mm + how.margin_frac * (worst - press) {
            short += 1;
        }
        let d = later - rest0;
        if d.is_finite() {
            more.push(d);
            frac.push(d / stop);
        }
        if a.each {
            println!(
                "chunk {}: pressed at {press:.3} mm, stop {stop:.2} mm, room {:.2} mm; the later presses' furthest rest {d:+.3} mm",
                n.chunk,
                n.end_mm - rest0
            );
        }
    }
    more.sort_by(f64::total_cmp);
    frac.sort_by(f64::total_cmp);
    let q = |v: &[f64], p: f64| {
        v.get(((v.len() as f64 - 1.0) * p).round() as usize)
            .copied()
            .unwrap_or(f64::NAN)
    };
    println!(
        "the later presses' furthest rest past the first's, over {} hold points: median {:+.3} mm, 90 % {:+.3} mm, 99 % {:+.3} mm, largest {:+.3} mm; as a fraction of the stop: 90 % {:+.4}, 99 % {:+.4}, largest {:+.4}",
        more.len(),
        q(&more, 0.5),
        q(&more, 0.9),
        q(&more, 0.99),
        q(&more, 1.0),
        q(&frac, 0.9),
        q(&frac, 0.99),
        q(&frac, 1.0)
    );
    println!(
        "hold points with a press that ran past the chunk's end: {past}; with one that left less room than the margins ({} mm and {} of the stop): {short}",
        how.margin_mm, how.margin_frac
    );
}
