#![allow(missing_docs)] // criterion_group! generates an undocumented function
//! Time of the feedrate override's transition (§4): on the Butterfly at
//! F = 5000 mm/min with the override levels 30, 50 and 125 %, from the
//! running plan at 20 points spread along the path to each level
//! (`OverrideContext::compute`: the transition window's LPs, the merge into
//! the level's plan). Before the measurements it prints what the points gave
//! (profiles, points where the override is skipped, failures).
//!
//!     cargo bench -p planner-host --bench override

use criterion::{criterion_group, criterion_main, Criterion};
use planner_host::{plan_curve, ArcLength, Limits, OverrideContext, OverrideOutcome, PlanConfig, TABLE1};

/// Points along the path the override is pressed at.
const POINTS: usize = 20;

fn transitions(c: &mut Criterion) {
    let curve = planner_host::builtin::butterfly().unwrap();
    let cfg = PlanConfig {
        limits: Limits {
            vbar: 5000.0 / 60.0,
            ..TABLE1
        },
        override_levels: vec![30.0, 50.0, 125.0],
        ..PlanConfig::default()
    };
    let plan = plan_curve(&curve, &cfg).unwrap();
    let arc = ArcLength::new(&curve);
    let ctx = OverrideContext::new(&curve, &arc, &plan).unwrap();
    let running = ctx.level_ctrl(0).unwrap().to_vec();
    let l = plan.path_length_mm;
    let at: Vec<f64> = (0..POINTS)
        .map(|k| l * (k as f64 + 0.5) / POINTS as f64)
        .collect();
    let levels: Vec<(u16, f64)> = (1..).map_while(|t| Some((t, ctx.level_percent(t)?))).collect();
    for &(t, pct) in &levels {
        let (mut profiles, mut skipped, mut failed) = (0, 0, 0);
        for &s in &at {
            match ctx.compute(0, &running, s, t) {
                Ok(OverrideOutcome::Profile(_)) => profiles += 1,
                Ok(_) => skipped += 1,
                Err(_) => failed += 1,
            }
        }
        eprintln!(
            "to {pct:.0} %: {profiles} profiles, {skipped} skipped, {failed} failed of {POINTS} points"
        );
    }
    let mut g = c.benchmark_group("override");
    g.sample_size(10);
    for &(t, pct) in &levels {
        g.bench_function(format!("butterfly_{POINTS}_points_to_{pct:.0}_percent"), |b| {
            b.iter(|| {
                at.iter()
                    .filter(|&&s| ctx.compute(0, &running, s, t).is_ok())
                    .count()
            })
        });
    }
    g.finish();
}

criterion_group!(benches, transitions);
criterion_main!(benches);
