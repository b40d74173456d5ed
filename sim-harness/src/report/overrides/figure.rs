//! The feed figure of one scenario run: planned and commanded feed against
//! arc length, the override levels' planned feed (paper's figures only),
//! and every override command, hold and resume marked where it happened.

use std::path::Path;

use firmware_core::path::qspline::QSpline;
use firmware_core::Table;

use crate::plot::feed::{plot_feed_marked, FeedPlot, Marker, MarkerKind};
use crate::report::overrides::run::{BoxError, Run};
use crate::run;

/// Draw `run`'s feed figure to `png`.
pub(crate) fn write_feed_figure(png: &Path, run: &Run) -> Result<(), BoxError> {
    let r = &run.result;
    let name = run.spec.name;
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
            level_series.push((
                format!("override level {:.0} %: planned feed", lv.alpha() * 100.0),
                pts,
            ));
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
    plot_feed_marked(
        png,
        &FeedPlot {
            title: &run.spec.title,
            planned: &planned,
            commanded: &commanded,
            actual: None,
            vbar_mm_s: Some(run.spec.vbar_mm_s),
            extra: &extra,
        },
        &markers(run),
    )?;
    Ok(())
}

/// The events of a run as markers: each override command at the setpoint's
/// arc length when it was given ("→ 50 %"), each hold where it was pressed,
/// each resume where the setpoint was when it was given.
fn markers(run: &Run) -> Vec<Marker> {
    let r = &run.result;
    let s_at = |t: f64| {
        let k = r.ticks.partition_point(|tk| tk.t_s < t);
        r.ticks.get(k).or(r.ticks.last()).map(|tk| tk.s_mm)
    };
    let mut v: Vec<Marker> = r
        .overrides
        .iter()
        .map(|o| Marker {
            s_mm: o.s_cmd_mm,
            kind: MarkerKind::Override,
            label: format!("→ {:.0} %", if o.level == 0 { 100.0 } else { o.percent }),
        })
        .collect();
    for h in &r.holds {
        v.push(Marker {
            s_mm: h.s_hold_mm,
            kind: MarkerKind::Hold,
            label: "hold".into(),
        });
        if let Some(s) = h.t_resume_s.and_then(s_at) {
            v.push(Marker {
                s_mm: s,
                kind: MarkerKind::Resume,
                label: "resume".into(),
            });
        }
    }
    v.sort_by(|a, b| a.s_mm.total_cmp(&b.s_mm));
    v
}
