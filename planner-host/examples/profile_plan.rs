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
    let mut cfg = PlanConfig {
        sampling,
        ..PlanConfig::default()
    };
    // optional overrides of the certified sequence: KEY=VALUE
    for a in args {
        let (k, v) = a.split_once('=').expect("KEY=VALUE");
        let v: f64 = v.parse().unwrap();
        let c = &mut cfg.certified;
        match k {
            "rho0" => c.rho0 = v,
            "shrink" => c.rho_shrink = v,
            "rho_min" => c.rho_min = v,
            "activity" => c.activity = v,
            "max_lps" => c.max_lps = v as usize,
            "stop_rel" => c.stop_rel = v,
            "checks" => c.checks_per_span = v as usize,
            "tol" => cfg.solver.tol_gap = v,
            "banded" => cfg.solver.banded = v != 0.0,
            _ => panic!("unknown {k}"),
        }
    }
    let mut totals = Vec::new();
    let mut lps = Vec::new();
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
        lps.push(lp_ms);
    }
    totals.sort_by(f64::total_cmp);
    lps.sort_by(f64::total_cmp);
    println!(
        "median total {:.1} ms, min total {:.1} ms, min LPs {:.1} ms",
        totals[totals.len() / 2],
        totals[0],
        lps[0]
    );
}
