//! PNG plot of the feedrate against arc length: the plan √q(s), the
//! simulated path speeds and the programmed feed.

use std::path::Path;

use plotters::prelude::*;

use crate::plot::png::{register_font, PlotError};

/// What to draw: series of (s in mm, speed in mm/s).
#[derive(Debug, Clone, Copy)]
pub struct FeedPlot<'a> {
    /// Title line.
    pub title: &'a str,
    /// The plan's feed √q(s) at dense points.
    pub planned: &'a [(f64, f64)],
    /// Path speed of the commanded setpoints |r₊ − r₋|/2T against their s.
    pub commanded: &'a [(f64, f64)],
    /// Path speed of the actual (servo) positions, if any.
    pub actual: Option<&'a [(f64, f64)]>,
    /// Tangential velocity limit v̄, mm/s, drawn as a dashed line.
    pub vbar_mm_s: Option<f64>,
    /// Further labelled series (e.g. the override's limiting profile), drawn
    /// in their own colours.
    pub extra: &'a [(&'a str, &'a [(f64, f64)])],
}

/// Image size, pixels.
pub(crate) const SIZE_PX: (u32, u32) = (1400, 800);

/// Draw the plot to `path` (PNG), atomically (temporary file, then rename).
pub fn plot_feed(path: &Path, p: &FeedPlot) -> Result<(), PlotError> {
    if p.planned.is_empty() && p.commanded.is_empty() {
        return Err(PlotError::Empty("no planned or commanded feed"));
    }
    register_font()?;
    let shown = path.display().to_string();
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let stem = path
        .file_stem()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    // the bitmap backend picks the encoder by extension: keep `.png`
    let tmp = dir.join(format!(".{stem}.{}.tmp.png", std::process::id()));
    let result = draw(&tmp, p).map_err(|message| PlotError::Draw {
        path: shown.clone(),
        message,
    });
    let result = result
        .and_then(|()| std::fs::rename(&tmp, path).map_err(|source| PlotError::Io { path: shown, source }));
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

fn finite(series: &[(f64, f64)]) -> impl Iterator<Item = (f64, f64)> + '_ {
    series
        .iter()
        .copied()
        .filter(|(x, y)| x.is_finite() && y.is_finite())
}

fn draw(path: &Path, p: &FeedPlot) -> Result<(), String> {
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
    let v_max = all()
        .map(|(_, v)| v)
        .fold(p.vbar_mm_s.unwrap_or(0.0), f64::max)
        .max(1e-9)
        * 1.3; // headroom for the legend above the curves
    let v_min = all().map(|(_, v)| v).fold(0.0, f64::min);

    let root = BitMapBackend::new(path, SIZE_PX).into_drawing_area();
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let mut chart = ChartBuilder::on(&root)
        .caption(p.title, ("sans-serif", 30))
        .margin(20)
        .x_label_area_size(60)
        .y_label_area_size(80)
        .build_cartesian_2d(s_min..s_max, v_min..v_max)
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .x_desc("arc length s [mm]")
        .y_desc("feed [mm/s]")
        .axis_desc_style(("sans-serif", 22))
        .label_style(("sans-serif", 18))
        .draw()
        .map_err(|e| e.to_string())?;

    if let Some(vbar) = p.vbar_mm_s {
        let dashes: Vec<(f64, f64)> = (0..200)
            .flat_map(|k| {
                let a = s_min + (s_max - s_min) * k as f64 / 200.0;
                let b = s_min + (s_max - s_min) * (k as f64 + 0.5) / 200.0;
                [(a, vbar), (b, vbar)]
            })
            .collect();
        chart
            .draw_series(
                dashes
                    .chunks(2)
                    .map(|seg| PathElement::new(seg.to_vec(), BLACK.stroke_width(2))),
            )
            .map_err(|e| e.to_string())?
            .label(format!("velocity limit {vbar:.1} mm/s"))
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(2)));
    }
    if let Some(actual) = p.actual {
        let style = RGBColor(230, 120, 0).stroke_width(2);
        chart
            .draw_series(LineSeries::new(finite(actual), style))
            .map_err(|e| e.to_string())?
            .label("simulated, actual (servo) positions")
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
    }
    const EXTRA: [RGBColor; 4] = [
        RGBColor(200, 0, 160),
        RGBColor(220, 30, 30),
        RGBColor(120, 120, 120),
        RGBColor(0, 170, 200),
    ];
    for (k, (label, series)) in p.extra.iter().enumerate() {
        let style = EXTRA[k % EXTRA.len()].stroke_width(2);
        chart
            .draw_series(LineSeries::new(finite(series), style))
            .map_err(|e| e.to_string())?
            .label(label.to_string())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
    }
    let style = RGBColor(0, 150, 60).stroke_width(2);
    chart
        .draw_series(LineSeries::new(finite(p.commanded), style))
        .map_err(|e| e.to_string())?
        .label("simulated, commanded setpoints |r(n+1) - r(n-1)| / 2T")
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
    let style = BLUE.stroke_width(1);
    chart
        .draw_series(LineSeries::new(finite(p.planned), style))
        .map_err(|e| e.to_string())?
        .label("plan sqrt(q(s))")
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperMiddle)
        .label_font(("sans-serif", 18))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(|e| e.to_string())?;
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
        plot_feed(&path, &p).unwrap();
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
