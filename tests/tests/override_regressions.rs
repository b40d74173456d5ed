//! Feedrate override computations (paper §4) that once failed, replayed from
//! what the host had.

use planner_host::feed_override::{OverrideContext, OverrideOutcome};
use planner_host::plan::{self, PlanConfig};
use planner_host::ArcLength;

/// The faults scenario: a new command while the host's scheduled
/// profile, a 120 % → 50 % transition, had not merged yet (q still at 120 %
/// where the window starts), to 30 %. The window LP bounded the feed by the
/// two levels only (50 %), so the profile's own fixed points broke its rows:
/// `PrimalInfeasible` after every retry. The bound now admits the active
/// profile itself; the profile must come out and keep the prefix bitwise.
#[test]
fn an_override_inside_an_unmerged_transition() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/fixtures/override/unmerged_transition.json"
    );
    let d: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    let curve = planner_host::builtin::butterfly().unwrap();
    let cfg = PlanConfig {
        limits: planner_host::limits::Limits {
            vbar: d["plan"]["vbar_mm_s"].as_f64().unwrap(),
            ..planner_host::limits::TABLE1
        },
        override_levels: d["plan"]["override_levels"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect(),
        ..PlanConfig::default()
    };
    let out = plan::plan_curve(&curve, &cfg).unwrap();
    let ctx = OverrideContext::new(&curve, &ArcLength::new(&curve), &out).unwrap();
    let base: Vec<f64> = d["base_ctrl"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    let level = d["base_level"].as_u64().unwrap() as u16;
    let s = d["s_at_mm"].as_f64().unwrap();
    let target = d["target"].as_u64().unwrap() as u16;
    // the situation: the active profile well above its level's feed there
    let vbar_level = ctx.level_vbar(level).unwrap();
    assert!(base.iter().cloned().fold(0.0, f64::max).sqrt() > 2.0 * vbar_level);
    match ctx.compute(level, &base, s, target) {
        Ok(OverrideOutcome::Profile(p)) => {
            let cut = p.first as usize + 3;
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&p.full_ctrl[..cut]), bits(&base[..cut]), "prefix");
            assert!(p.splice_s_mm >= s);
            eprintln!(
                "{:?}: splice {:.2} merge {:.2} mm, {} retries, {:.2} ms",
                p.case,
                p.splice_s_mm,
                p.merge_s_mm,
                p.retries_grow + p.retries_extreme,
                p.compute_time_s * 1e3
            );
        }
        other => panic!("override at {s} mm to level {target}: {other:?}"),
    }
}
