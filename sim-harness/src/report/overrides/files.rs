//! The files of one scenario run: its CSV, its feed figure, and its row of
//! the Markdown table.

use std::path::{Path, PathBuf};

use firmware_core::qspline::QSpline;
use firmware_core::table::Table;

use crate::plot::feed::{plot_feed, FeedPlot};
use crate::report::overrides::run::{BoxError, Run};
use crate::report::overrides::table::{fmt_opt, median_max};
use crate::run;
use crate::scenario::record::Fate;

/// Write `<name>.csv`, `<name>_feed.png` and return the Markdown row.
pub fn write_run(out: &Path, run: &Run) -> Result<(String, Vec<PathBuf>), BoxError> {
    let r = &run.result;
    let name = run.spec.name;
    let csv = out.join(format!("{name}.csv"));
    crate::csv::write_csv(&csv, &r.ticks)?;
    let table = Table::parse(&run.table_bytes).map_err(|e| format!("{e:?}"))?;
    let planned = run::planned_feed(&table, 4000);
    let mut level_series: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    for k in 1..=table.level_count() {
        let Some(lv) = table.level(k as u16) else { continue };
        if let Some(q) = QSpline::new(table.q_knots(), lv.ctrl()) {
            let (a, b) = q.domain().unwrap_or((0.0, 0.0));
            let pts = (0..2000)
                .filter_map(|i| {
                    let s = a + (b - a) * i as f64 / 1999.0;
                    Some((s, q.eval(s)?[0].max(0.0).sqrt()))
                })
                .collect();
            level_series.push((format!("limiting profile {:.0} %", lv.alpha() * 100.0), pts));
        }
    }
    let h = r.metrics.period_s;
    let cmd: Vec<[f64; 3]> = r.ticks.iter().map(|t| t.cmd_mm).collect();
    let commanded: Vec<(f64, f64)> = crate::metrics::path_speed(&cmd, h)
        .into_iter()
        .enumerate()
        .map(|(k, v)| (r.ticks[k + 1].s_mm, v))
        .collect();
    let extra: Vec<(&str, &[(f64, f64)])> = level_series
        .iter()
        .take(if name.starts_with("fig") { 4 } else { 0 })
        .map(|(l, s)| (l.as_str(), s.as_slice()))
        .collect();
    let png = out.join(format!("{name}_feed.png"));
    plot_feed(
        &png,
        &FeedPlot {
            title: &format!("{name}: feed against arc length ({})", run.spec.what),
            planned: &planned,
            commanded: &commanded,
            actual: None,
            vbar_mm_s: Some(run.spec.vbar_mm_s),
            extra: &extra,
        },
    )?;
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
    let row = format!(
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
    );
    Ok((row, vec![csv, png]))
}
