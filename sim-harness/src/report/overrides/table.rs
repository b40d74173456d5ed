//! One scenario's row of the Markdown table: fates of the override
//! commands, latencies, host compute times, ratios to the limits.

use crate::report::overrides::run::Run;
use crate::scenario::record::Fate;

/// `a / b` of a (median, max) pair scaled and rounded, `–` if none.
pub(crate) fn fmt_opt(x: Option<(f64, f64)>, scale: f64, digits: usize) -> String {
    match x {
        Some((a, b)) => format!("{:.*} / {:.*}", digits, a * scale, digits, b * scale),
        None => "–".into(),
    }
}

/// The Markdown header of the report table.
pub const TABLE_HEAD: &str = "| scenario | time s | active/superseded/skipped/failed/commands | refusals | latency ms (median / max) | host compute ms (median / max) | Case II / retries | transition / ArcLen (median / max) | feed err after merge mm/s | acc / jerk / tacc / tjerk (pad-rest) | max step / v·T | ends at r(1) |\n|---|---|---|---|---|---|---|---|---|---|---|---|";

/// Order statistics of a sample: (median, max); `None` if empty.
pub fn median_max(v: &[f64]) -> Option<(f64, f64)> {
    let mut v: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    let med = if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    };
    Some((med, v[n - 1]))
}

/// The Markdown row of a run ([`TABLE_HEAD`]'s columns).
pub(crate) fn table_row(run: &Run) -> String {
    let r = &run.result;
    let name = run.spec.name;
    let ov = &r.overrides;
    let count = |f: &dyn Fn(&Fate) -> bool| ov.iter().filter(|o| f(&o.fate)).count();
    let lat: Vec<f64> = ov.iter().filter_map(|o| o.latency_s()).collect();
    let comp: Vec<f64> = ov.iter().flat_map(|o| o.compute_s.iter().copied()).collect();
    let case2 = ov
        .iter()
        .filter(|o| o.case.as_deref().is_some_and(|c| c.contains("II")))
        .count();
    let retries: u32 = ov.iter().map(|o| o.retries_grow + o.retries_extreme).sum();
    let ratio_len: Vec<f64> = ov
        .iter()
        .filter(|o| o.fate == Fate::Active)
        .filter_map(|o| Some(o.transition_len_mm? / o.arclen_estimate_mm.filter(|&a| a > 0.0)?))
        .collect();
    let feed_err = ov
        .iter()
        .filter_map(|o| o.feed_err_after_merge_mm_s)
        .fold(0.0, f64::max);
    let rest = &r.metrics.ratios_at_rest;
    let refusals: usize = ov.iter().map(|o| o.refusals.len()).sum();
    format!(
        "| {name} | {:.3} | {}/{}/{}/{}/{} | {} | {} | {} | {case2} / {retries} | {} | {:.2e} | {:.3} / {:.3} / {:.3} / {:.3} | {:.3} | {} |",
        r.metrics.machining_time_s,
        count(&|f| *f == Fate::Active),
        count(&|f| matches!(f, Fate::Superseded | Fate::Replaced)),
        count(&|f| matches!(f, Fate::Skipped(_))),
        count(&|f| matches!(f, Fate::Failed(_))),
        ov.len(),
        refusals,
        fmt_opt(median_max(&lat), 1e3, 1),
        fmt_opt(median_max(&comp), 1e3, 2),
        fmt_opt(median_max(&ratio_len), 1.0, 2),
        feed_err,
        rest.acc,
        rest.jerk,
        rest.tacc,
        rest.tjerk,
        r.max_step_mm / r.jump_limit_mm,
        if r.ended_at_end { "yes" } else { "NO" },
    )
}
