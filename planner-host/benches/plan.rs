#![allow(missing_docs)] // criterion_group! generates an undocumented function
//! Whole-plan time of the Butterfly (LEN, ADA, PAR; 1 point/mm, Table 1), default
//! (certified) formulation: geometry, every LP of the sequence, the s → u map
//! and the table. The target is a median of at most 100 ms on a 2-core machine.
//! Beside it, the geometry's steps on their own: the arc length, the s → u map
//! of the table and the PAR and ADA samplings at 1 and 10 points/mm.
//!
//!     cargo bench -p planner-host --bench plan

use criterion::{criterion_group, criterion_main, Criterion};
use planner_host::plan::su_fit::{SuMap, DEFAULT_TOL_MM};
use planner_host::plan::{self, PlanConfig};
use planner_host::sampling::{sample, Sampling};
use planner_host::ArcLength;

fn butterfly(c: &mut Criterion) {
    let curve = planner_host::builtin::butterfly().unwrap();
    let cfg = PlanConfig::default();
    let mut g = c.benchmark_group("plan");
    g.sample_size(20);
    g.bench_function("butterfly_len_1pt_mm_certified", |b| {
        b.iter(|| plan::plan_curve(&curve, &cfg).unwrap())
    });
    let ada = PlanConfig {
        sampling: planner_host::sampling::Sampling::ada_default(),
        ..PlanConfig::default()
    };
    g.bench_function("butterfly_ada_1pt_mm_certified", |b| {
        b.iter(|| plan::plan_curve(&curve, &ada).unwrap())
    });
    let par = PlanConfig {
        sampling: planner_host::sampling::Sampling::Par,
        ..PlanConfig::default()
    };
    g.bench_function("butterfly_par_1pt_mm_certified", |b| {
        b.iter(|| plan::plan_curve(&curve, &par).unwrap())
    });
    g.finish();
}

fn geometry(c: &mut Criterion) {
    let curve = planner_host::builtin::butterfly().unwrap();
    let mut g = c.benchmark_group("geometry");
    g.sample_size(20);
    g.bench_function("butterfly_arc_length", |b| b.iter(|| ArcLength::new(&curve)));
    let arc = ArcLength::new(&curve);
    g.bench_function("butterfly_su_map", |b| {
        b.iter(|| SuMap::fit(&curve, &arc, DEFAULT_TOL_MM).unwrap())
    });
    // (383 and 3,829 points: 1 and 10 per mm of the 382.9 mm path)
    for m in [383, 3829] {
        for (name, method) in [("par", Sampling::Par), ("ada", Sampling::ada_default())] {
            g.bench_function(format!("butterfly_sample_{name}_{m}"), |b| {
                b.iter(|| sample(&curve, &arc, method, m).unwrap())
            });
        }
    }
    g.finish();
}

criterion_group!(benches, butterfly, geometry);
criterion_main!(benches);
