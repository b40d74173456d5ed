//! PNG of a whole program run: the commanded toolpath seen from above (X
//! right, Y up; Z is not drawn), each servo tick's segment coloured by the
//! planned feed at it, from blue (at rest) through green to red (the
//! fastest feed of the run); rapids drawn thin and grey.

use std::path::Path;

use plotters::prelude::*;

use crate::plot::png::{draw_err, png, register_font, PlotError};
use crate::plot::style::title_px;
use crate::program::ProgramRun;
use planner_host::program::EntryKind;

/// Image size, pixels.
const SIZE_PX: (u32, u32) = (1200, 1000);

/// Blue → cyan → green → yellow → red for `x` in [0, 1].
fn colormap(x: f64) -> RGBColor {
    let x = if x.is_finite() { x.clamp(0.0, 1.0) } else { 0.0 };
    let h = (1.0 - x) * 240.0 / 360.0;
    let (r, g, b) = HSLColor(h, 0.9, 0.45).to_rgba().rgb();
    RGBColor(r, g, b)
}

/// Draw the program's toolpath coloured by feed to `path` (PNG, atomically).
pub fn plot_program(path: &Path, run: &ProgramRun, name: &str) -> Result<(), PlotError> {
    if run.ticks.len() < 2 {
        return Err(PlotError::Empty("no setpoints"));
    }
    register_font()?;
    let rapid_of = |i: usize| {
        let p = run.path_of_tick[i] as usize;
        run.paths
            .get(p.wrapping_sub(1))
            .is_some_and(|p| p.kind == EntryKind::Rapid)
    };
    let vmax = (0..run.ticks.len())
        .filter(|&i| !rapid_of(i))
        .map(|i| run.ticks[i].feed_mm_s)
        .fold(0.0f64, f64::max)
        .max(1e-9);
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for t in &run.ticks {
        for k in 0..2 {
            lo[k] = lo[k].min(t.cmd_mm[k]);
            hi[k] = hi[k].max(t.cmd_mm[k]);
        }
    }
    // about equal scales on both axes (the chart is ASPECT times as high as
    // wide), a margin of 4 %
    const ASPECT: f64 = 0.86;
    let mut sx = (hi[0] - lo[0]).max(1e-6) * 1.08;
    let mut sy = (hi[1] - lo[1]).max(1e-6) * 1.08;
    if sy > sx * ASPECT {
        sx = sy / ASPECT;
    } else {
        sy = sx * ASPECT;
    }
    let c = [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0];
    let (x0, x1) = (c[0] - sx / 2.0, c[0] + sx / 2.0);
    let (y0, y1) = (c[1] - sy / 2.0, c[1] + sy / 2.0);
    let title = format!(
        "{name}: toolpath (XY) coloured by feed, 0 (blue) to {vmax:.1} mm/s (red); rapids grey; {:.3} s",
        run.machining_time_s()
    );
    png(path, SIZE_PX, |root| {
        root.fill(&WHITE).map_err(draw_err(path))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(&title, ("sans-serif", title_px(&title, SIZE_PX.0, 24)))
            .margin(16)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(draw_err(path))?;
        chart
            .configure_mesh()
            .x_desc("X, mm")
            .y_desc("Y, mm")
            .draw()
            .map_err(draw_err(path))?;
        let mut segs = Vec::with_capacity(run.ticks.len());
        for i in 1..run.ticks.len() {
            if run.path_of_tick[i] != run.path_of_tick[i - 1] {
                continue;
            }
            let (a, b) = (run.ticks[i - 1].cmd_mm, run.ticks[i].cmd_mm);
            let style = if rapid_of(i) {
                RGBColor(170, 170, 170).stroke_width(1)
            } else {
                colormap(run.ticks[i].feed_mm_s / vmax).stroke_width(3)
            };
            segs.push(PathElement::new(vec![(a[0], a[1]), (b[0], b[1])], style));
        }
        chart.draw_series(segs).map_err(draw_err(path))?;
        root.present().map_err(draw_err(path))?;
        Ok(())
    })
}
