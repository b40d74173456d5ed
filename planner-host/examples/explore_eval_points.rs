//! How many evaluation points does the paper's
//! formulation need before the limits hold between them, what does it cost,
//! and what does re-linearising the jerk rows around the last plan gain?
//!
//!     cargo run --release -p planner-host --example explore_eval_points [CURVE.json | NAME]

use std::time::Instant;

use planner_host::geometry::path_derivs_at;
use planner_host::limits::TABLE1;
use planner_host::lp::{self, BasisRow, EvalPoint, FeedLp, Objective, QhatBound};
use planner_host::plan::machining_time;
use planner_host::plan::su_fit::SuMap;
use planner_host::plan::verify;
use planner_host::sampling::{self, Sampling};
use planner_host::ArcLength;
use planner_host::Nurbs;

fn main() {
    let path = std::env::args().nth(1);
    let curve = match path {
        Some(p) => match planner_host::builtin::by_name(&p) {
            Some(c) => c.unwrap(),
            None => Nurbs::load(std::path::Path::new(&p)).unwrap(),
        },
        None => planner_host::builtin::butterfly().unwrap(),
    };
    let arc = ArcLength::new(&curve);
    let len = arc.total();
    let su = SuMap::fit(&curve, &arc, 1e-6).unwrap();
    for sampling in [Sampling::Len, Sampling::ada_default()] {
        let m = sampling::points_for_density(len, 1.0);
        let samples = sampling::sample(&curve, &arc, sampling, m).unwrap();
        let knots = lp::knot_vector(&samples);
        let greville = lp::greville(&knots);
        let variants: Vec<(String, Vec<f64>)> = vec![
            ("greville".into(), greville.clone()),
            ("greville+3/span".into(), with_per_span(&greville, &knots, 3)),
            ("greville+su-breaks".into(), merge(&greville, &su.breaks)),
            (
                "greville+3/span+su-breaks".into(),
                merge(&with_per_span(&greville, &knots, 3), &su.breaks),
            ),
        ];
        for (name, pts) in variants {
            let t0 = Instant::now();
            let points: Vec<EvalPoint> = pts
                .iter()
                .filter_map(|&s| {
                    Some(EvalPoint {
                        s,
                        geo: path_derivs_at(&curve, &arc, s),
                        basis: BasisRow::at(&knots, s)?,
                    })
                })
                .collect();
            let mk = |qb| FeedLp {
                knots: &knots,
                points: &points,
                limits: TABLE1,
                objective: Objective::Integral,
                qhat_bound: qb,
                settings: Default::default(),
                ends: None,
                feed: None,
            };
            let pseudo = mk(QhatBound::ControlPoints).solve_pseudo_jerk().unwrap();
            let plan = mk(QhatBound::ControlPoints).solve_plan(&pseudo.ctrl).unwrap();
            let dt = t0.elapsed().as_secs_f64();
            let d = verify::dense_check(&curve, &arc, &knots, &plan.ctrl, &TABLE1, 20);
            let t = machining_time(&knots, &plan.ctrl);
            println!(
                "{sampling:>18} {name:<28} points {:>5} rows {:>6}  T {:.4} s  solve {:>6.1} ms  dense acc {:.3} jerk {:.3} tacc {:.3} tjerk {:.3}",
                points.len(),
                plan.stats.rows,
                t,
                dt * 1e3,
                d.ratios.acc,
                d.ratios.jerk,
                d.ratios.tacc,
                d.ratios.tjerk
            );
            // re-linearise around the last plan: rows with √q_k, bound a ≤ (1 + δ)·a_k ∧ â
            let mut cur = plan.ctrl.clone();
            for it in 0..4 {
                let bound: Vec<f64> = cur
                    .iter()
                    .zip(&pseudo.ctrl)
                    .map(|(a, h)| (a * 1.3 + 1.0).min(*h))
                    .collect();
                let t1 = Instant::now();
                let next = match mk(QhatBound::ControlPoints).solve_plan(&bound) {
                    Ok(n) => n,
                    Err(e) => {
                        println!("    relinearise {it}: {e}");
                        break;
                    }
                };
                let d = verify::dense_check(&curve, &arc, &knots, &next.ctrl, &TABLE1, 20);
                println!(
                    "    relinearise {it}: T {:.4} s  {:>6.1} ms  dense acc {:.3} jerk {:.3} tjerk {:.3}",
                    machining_time(&knots, &next.ctrl),
                    t1.elapsed().as_secs_f64() * 1e3,
                    d.ratios.acc,
                    d.ratios.jerk,
                    d.ratios.tjerk
                );
                cur = next.ctrl;
            }
        }
    }
}

fn with_per_span(base: &[f64], knots: &[f64], k: usize) -> Vec<f64> {
    let mut v = base.to_vec();
    for w in knots.windows(2).filter(|w| w[1] > w[0]) {
        for i in 1..=k {
            v.push(w[0] + (w[1] - w[0]) * i as f64 / (k + 1) as f64);
        }
    }
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    v.dedup();
    v
}

fn merge(a: &[f64], b: &[f64]) -> Vec<f64> {
    let mut v: Vec<f64> = a.iter().chain(b).copied().collect();
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    v.dedup_by(|x, y| (*x - *y).abs() < 1e-9);
    v
}
