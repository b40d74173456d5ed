#![allow(missing_docs)] // criterion_group! generates an undocumented function
//! Whole-plan time of the Butterfly (LEN, ADA, PAR; 1 point/mm, Table 1), default
//! (certified) formulation: geometry, every LP of the sequence, the s → u map
//! and the table. The target is a median of at most 100 ms on a 2-core machine.
//!
//!     cargo bench -p planner-host --bench plan

use criterion::{criterion_group, criterion_main, Criterion};
use planner_host::plan::{self, PlanConfig};

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

criterion_group!(benches, butterfly);
criterion_main!(benches);
