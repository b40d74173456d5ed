//! Repeatedly plan the Butterfly (1 point/mm, default settings) for profiling:
//! prints the geometry time, each LP's time and iterations, and the total.
//!
//!     cargo run --release -p planner-host --example profile_plan -- [par|len|ada] [REPEATS]

use planner_host::plan::{self, PlanConfig};

fn main() {
    let mut args = std::env::args().skip(1);
    let sampling = args.next().unwrap_or_else(|| "len".into()).parse().unwrap();
    let reps: usize = args.next().map_or(10, |s| s.parse().unwrap());
    let curve = planner_host::builtin::butterfly().unwrap();
    let cfg = PlanConfig {
        sampling,
        ..PlanConfig::default()
    };
    let mut totals = Vec::new();
    for _ in 0..reps {
        let out = plan::plan_curve(&curve, &cfg).unwrap();
        let lp_ms: f64 = out.lp.iter().map(|l| l.solve_time_s * 1e3).sum();
        let its: u32 = out.lp.iter().map(|l| l.iterations).sum();
        println!(
            "T {:.4} geometry {:.1} ms, {} LPs {:.1} ms ({} its), total {:.1} ms",
            out.predicted_time_s,
            out.geometry_time_s * 1e3,
            out.lp.len(),
            lp_ms,
            its,
            out.total_time_s * 1e3
        );
        totals.push(out.total_time_s * 1e3);
    }
    totals.sort_by(f64::total_cmp);
    println!("median total {:.1} ms", totals[totals.len() / 2]);
}
