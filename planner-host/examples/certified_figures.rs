//! Planning figures of the benchmark curves: every curve × PAR/LEN/ADA × density, planned with the
//! default (certified) formulation, or `--formulation paper`: predicted time,
//! the largest dense ratio to each limit (20 and 200 points per knot span),
//! LPs and planning time.
//!
//!     cargo run --release -p planner-host --example certified_figures -- [--formulation F] [--densities 0.5,1,2] [CURVE.json | NAME ...]
//!
//! Without curves: the five built-in ones.

use planner_host::plan::{self, Formulation, PlanConfig};
use planner_host::sampling::Sampling;
use planner_host::ArcLength;
use planner_host::Nurbs;

fn main() {
    let mut args = std::env::args().skip(1);
    let mut curves = Vec::new();
    let mut formulation = Formulation::Certified;
    let mut densities = vec![0.5, 1.0, 2.0];
    let mut samplings = vec![Sampling::Par, Sampling::Len, Sampling::ada_default()];
    let mut verbose = false;
    while let Some(a) = args.next() {
        match a.as_str() {
            "--formulation" => formulation = args.next().unwrap().parse().unwrap(),
            "--densities" => {
                densities = args
                    .next()
                    .unwrap()
                    .split(',')
                    .map(|x| x.parse().unwrap())
                    .collect()
            }
            "--samplings" => {
                samplings = args
                    .next()
                    .unwrap()
                    .split(',')
                    .map(|x| x.parse().unwrap())
                    .collect()
            }
            "-v" => verbose = true,
            _ => curves.push(a),
        }
    }
    if curves.is_empty() {
        curves = planner_host::builtin::NAMES
            .iter()
            .map(|n| n.to_string())
            .collect();
    }
    println!(
        "| curve | sampling | pts/mm | T (s) | vel | acc | jerk | feed | tacc | tjerk | jerk@200 | tjerk@200 | LPs | IPM its | plan ms |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for path in &curves {
        let curve = match planner_host::builtin::by_name(path) {
            Some(c) => c.unwrap(),
            None => Nurbs::load(std::path::Path::new(path)).unwrap(),
        };
        let arc = ArcLength::new(&curve);
        for &sampling in &samplings {
            for &density in &densities {
                let cfg = PlanConfig {
                    formulation,
                    sampling,
                    density_per_mm: density,
                    objective: planner_host::lp::Objective::Uniform,
                    qhat_bound: planner_host::lp::QhatBound::None,
                    ..PlanConfig::default()
                };
                let name = curve.name.clone();
                match plan::plan_curve(&curve, &cfg) {
                    Ok(out) => {
                        let d = out.dense_check(&curve, &arc, 20);
                        let f = out.dense_check(&curve, &arc, 200);
                        let r = d.ratios;
                        let its: u32 = out.lp.iter().map(|l| l.iterations).sum();
                        println!(
                            "| {name} | {sampling} | {density} | {:.4} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} | {} | {} | {:.1} |",
                            out.predicted_time_s,
                            r.vel,
                            r.acc,
                            r.jerk,
                            r.feed,
                            r.tacc,
                            r.tjerk,
                            f.ratios.jerk,
                            f.ratios.tjerk,
                            out.lp.len(),
                            its,
                            out.total_time_s * 1e3
                        );
                        if verbose {
                            eprint!("{}", out.summary(Some(&d)));
                            eprintln!("  check {:?}  argmax {:?}", out.check, d.argmax_s);
                        }
                    }
                    Err(e) => println!("| {name} | {sampling} | {density} | error: {e} |"),
                }
            }
        }
    }
}
