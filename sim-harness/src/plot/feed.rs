//! PNG plot of the feedrate against arc length: the plan √q(s), the
//! simulated path speeds, the programmed feed and event markers
//! (override commands, feed holds, resumes); the legend below the chart.

use std::path::Path;

use plotters::element::DashedPathElement;
use plotters::prelude::*;

use crate::plot::png::{register_font, PlotError};
use crate::plot::style::{draw_legend, legend_height, title_px, Dash, Line};

/// What to draw: series of (s in mm, speed in mm/s).
#[derive(Debug, Clone, Copy)]
pub struct FeedPlot<'a> {
    /// Title line (its font shrinks to fit the image width).
    pub title: &'a str,
    /// The plan's feed √q(s) at dense points.
    pub planned: &'a [(f64, f64)],
    /// Path speed of the commanded setpoints |r₊ − r₋|/2T against their s.
    pub commanded: &'a [(f64, f64)],
    /// Path speed of the actual (servo) positions, if any.
    pub actual: Option<&'a [(f64, f64)]>,
    /// The programmed feed v̄ (the table's tangential feed limit), mm/s,
    /// drawn as a dashed black line.
    pub vbar_mm_s: Option<f64>,
    /// Further labelled series (e.g. an override level's planned feed),
    /// drawn dashed in their own colours.
    pub extra: &'a [(&'a str, &'a [(f64, f64)])],
}

/// What an event marker stands for (its colour).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MarkerKind {
    /// An override command.
    Override,
    /// A feed hold pressed.
    Hold,
    /// A resume after a hold.
    Resume,
}

/// An event marked on a feed plot: a vertical line at `s_mm` with a short label.
#[derive(Debug, Clone, PartialEq)]
pub struct Marker {
    /// Where, arc length in mm.
    pub s_mm: f64,
    /// What happened there.
    pub kind: MarkerKind,
    /// A short label (e.g. "→ 50 %", "hold", "resume").
    pub label: String,
}

/// Image size, pixels.
pub(crate) const SIZE_PX: (u32, u32) = (1400, 800);

/// Labels are drawn only when a plot has at most this many markers
/// (beyond, the markers stand alone as short ticks at the top).
const MAX_LABELLED: usize = 24;

/// Draw the plot to `path` (PNG), atomically (temporary file, then rename).
pub fn plot_feed(path: &Path, p: &FeedPlot) -> Result<(), PlotError> {
    plot_feed_marked(path, p, &[])
}

/// [`plot_feed`] with event markers (override commands, holds, resumes).
pub fn plot_feed_marked(path: &Path, p: &FeedPlot, markers: &[Marker]) -> Result<(), PlotError> {
    if p.planned.is_empty() && p.commanded.is_empty() {
        return Err(PlotError::Empty("no planned or commanded feed"));
    }
    register_font()?;
    let shown = path.display().to_string();
    // the bitmap backend picks the encoder by extension: keep `.png`
    let tmp = planner_host::plan::temp_beside(path, ".png");
    let result = draw(&tmp, p, markers).map_err(|message| PlotError::Draw {
        path: shown.clone(),
        message,
    });
    match result {
        Ok(()) => planner_host::plan::replace_with(&tmp, path)
            .map_err(|source| PlotError::Io { path: shown, source }),
        Err(e) => {
            let _ = std::fs::remove_file(&tmp);
            Err(e)
        }
    }
}

fn finite(series: &[(f64, f64)]) -> impl Iterator<Item = (f64, f64)> + '_ {
    series
        .iter()
        .copied()
        .filter(|(x, y)| x.is_finite() && y.is_finite())
}

const EXTRA: [RGBColor; 4] = [
    RGBColor(200, 0, 160),
    RGBColor(220, 30, 30),
    RGBColor(120, 120, 120),
    RGBColor(0, 170, 200),
];

fn marker_color(k: MarkerKind) -> RGBColor {
    match k {
        MarkerKind::Override => RGBColor(150, 60, 200),
        MarkerKind::Hold => RGBColor(210, 30, 30),
        MarkerKind::Resume => RGBColor(0, 140, 70),
    }
}

fn draw(path: &Path, p: &FeedPlot, markers: &[Marker]) -> Result<(), String> {
    let all = || {
        finite(p.planned)
            .chain(finite(p.commanded))
            .chain(p.actual.into_iter().flat_map(finite))
            .chain(p.extra.iter().flat_map(|(_, e)| finite(e)))
    };
    let s_max = all().map(|(s, _)| s).fold(0.0, f64::max).max(1e-9);
    let s_min = all()
        .map(|(s, _)| s)
        .fold(f64::INFINITY, f64::min)
        .min(s_max - 1e-9);
    let top = all()
        .map(|(_, v)| v)
        .fold(p.vbar_mm_s.unwrap_or(0.0), f64::max)
        .max(1e-9);
    let labelled = !markers.is_empty() && markers.len() <= MAX_LABELLED;
    // headroom for the marker labels above the curves
    let v_max = top * if labelled { 1.22 } else { 1.08 };
    let v_min = all().map(|(_, v)| v).fold(0.0, f64::min);

    // the lines, back to front; the legend lists them front to back
    let mut lines: Vec<(Line, Vec<(f64, f64)>)> = Vec::new();
    if let Some(vbar) = p.vbar_mm_s {
        lines.push((
            Line::new(
                format!("programmed feed {vbar:.1} mm/s"),
                BLACK,
                2,
                Dash::Dashed(10, 6),
            ),
            vec![(s_min, vbar), (s_max, vbar)],
        ));
    }
    lines.push((
        Line::new("planned feed √q(s)", RGBColor(120, 170, 255), 5, Dash::Solid),
        finite(p.planned).collect(),
    ));
    for (k, (label, series)) in p.extra.iter().enumerate() {
        lines.push((
            Line::new(*label, EXTRA[k % EXTRA.len()], 2, Dash::Dashed(14, 5)),
            finite(series).collect(),
        ));
    }
    if let Some(actual) = p.actual {
        lines.push((
            Line::new(
                "simulated feed, actual (servo) positions",
                RGBColor(230, 120, 0),
                2,
                Dash::Dashed(4, 4),
            ),
            finite(actual).collect(),
        ));
    }
    lines.push((
        Line::new(
            "simulated feed, commanded setpoints |r(n+1) − r(n−1)| / 2T",
            RGBColor(0, 110, 40),
            1,
            Dash::Solid,
        ),
        finite(p.commanded).collect(),
    ));
    let mut legend: Vec<Line> = lines.iter().map(|(l, _)| l.clone()).collect();
    for kind in [MarkerKind::Override, MarkerKind::Hold, MarkerKind::Resume] {
        let n = markers.iter().filter(|m| m.kind == kind).count();
        if n > 0 {
            let what = match kind {
                MarkerKind::Override => "override command",
                MarkerKind::Hold => "feed hold pressed",
                MarkerKind::Resume => "resume",
            };
            let label = if n == 1 {
                what.to_string()
            } else {
                format!("{what} ({n})")
            };
            legend.push(Line::new(label, marker_color(kind), 2, Dash::Dashed(3, 3)));
        }
    }

    let root = BitMapBackend::new(path, SIZE_PX).into_drawing_area();
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let title_px = title_px(p.title, SIZE_PX.0, 28);
    let root = root
        .titled(p.title, ("sans-serif", title_px))
        .map_err(|e| e.to_string())?;
    let legend_font = 17;
    let legend_h = legend_height(legend.len(), 2, legend_font);
    let (_, h) = root.dim_in_pixel();
    let (upper, lower) = root.split_vertically(h.saturating_sub(legend_h));
    let mut chart = ChartBuilder::on(&upper)
        .margin(15)
        .margin_right(30)
        .x_label_area_size(55)
        .y_label_area_size(80)
        .build_cartesian_2d(s_min..s_max, v_min..v_max)
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .x_desc("arc length s [mm]")
        .y_desc("feed [mm/s]")
        .axis_desc_style(("sans-serif", 22))
        .label_style(("sans-serif", 18))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(|e| e.to_string())?;

    // markers under the curves
    let mut rows: Vec<f64> = Vec::new(); // right end (mm) of the last label in each row
    let px_per_mm = (SIZE_PX.0 as f64 - 125.0) / (s_max - s_min);
    for m in markers.iter().filter(|m| m.s_mm.is_finite()) {
        let color = marker_color(m.kind);
        if labelled {
            chart.draw_series(std::iter::once(DashedPathElement::new(
                vec![(m.s_mm, v_min), (m.s_mm, top * 1.02)],
                3,
                3,
                color.stroke_width(1),
            )))
        } else {
            // too many to label: a short tick at the top edge each
            chart.draw_series(std::iter::once(PathElement::new(
                vec![(m.s_mm, top * 1.03), (m.s_mm, v_max)],
                color.stroke_width(1),
            )))
        }
        .map_err(|e| e.to_string())?;
        if labelled {
            let width_mm = (m.label.chars().count() as f64 * 0.6 * 15.0 + 6.0) / px_per_mm;
            let row = match rows.iter().position(|&end| end < m.s_mm) {
                Some(r) => r,
                None => {
                    rows.push(f64::NEG_INFINITY);
                    rows.len() - 1
                }
            };
            rows[row] = m.s_mm + width_mm;
            let y = top * 1.04 + (v_max - top * 1.04) * 0.28 * (row % 3) as f64;
            chart
                .draw_series(std::iter::once(Text::new(
                    m.label.clone(),
                    (m.s_mm, y),
                    ("sans-serif", 15).into_font().color(&color),
                )))
                .map_err(|e| e.to_string())?;
        }
    }
    for (line, pts) in lines {
        line.draw(&mut chart, pts)?;
    }
    draw_legend(&lower, &legend, 2, legend_font, 95)?;
    root.present().map_err(|e| e.to_string())?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_a_png() {
        let dir = std::env::temp_dir().join(format!("feedsim-plot-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("feed.png");
        let planned: Vec<(f64, f64)> = (0..=500)
            .map(|k| {
                (
                    k as f64 * 0.2,
                    150.0 * (k as f64 / 500.0 * std::f64::consts::PI).sin(),
                )
            })
            .collect();
        let commanded: Vec<(f64, f64)> = planned.iter().map(|&(s, v)| (s, v * 0.999)).collect();
        let p = FeedPlot {
            title: "test feed",
            planned: &planned,
            commanded: &commanded,
            actual: Some(&commanded),
            vbar_mm_s: Some(166.7),
            extra: &[("limiting profile", &commanded)],
        };
        let markers = [
            Marker {
                s_mm: 20.0,
                kind: MarkerKind::Override,
                label: "→ 50 %".into(),
            },
            Marker {
                s_mm: 60.0,
                kind: MarkerKind::Hold,
                label: "hold".into(),
            },
        ];
        plot_feed_marked(&path, &p, &markers).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert!(bytes.len() > 10_000, "{} bytes", bytes.len());
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
        assert_eq!(
            std::fs::read_dir(&dir).unwrap().count(),
            1,
            "temporary file left behind"
        );
        let empty = FeedPlot {
            planned: &[],
            commanded: &[],
            actual: None,
            ..p
        };
        assert!(plot_feed(&path, &empty).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
