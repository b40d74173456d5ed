//! The study's figures: sampling points on the curve (cf. the paper's
//! Figs 1–4), machining time against density (Figs 5–8) and the planned
//! feed against arc length per method (Figs 9–12).

use std::path::Path;

use planner_host::sampling;
use planner_host::ArcLength;
use planner_host::Nurbs;
use plotters::prelude::*;

use crate::plot::png::{draw_err, png, PlotError};
use crate::plot::style::{draw_legend, light, title_px, Dash, Line};
use crate::report::sampling::config::{ReportConfig, METHODS};
use crate::report::sampling::results::{sim_t, Report};
use crate::run::Series;

const W: u32 = 1000;
const COLORS: [RGBColor; 3] = [
    RGBColor(200, 40, 40),
    RGBColor(30, 110, 200),
    RGBColor(20, 150, 60),
];

/// The dash pattern of formulation `fi`: solid, dashed, dotted.
fn formulation_dash(fi: usize) -> Dash {
    match fi {
        0 => Dash::Solid,
        1 => Dash::Dashed(10, 6),
        _ => Dash::Dashed(3, 5),
    }
}

/// Sampling points of every method on the curve, one panel per method.
pub(crate) fn fig_sampling(path: &Path, c: &Nurbs, arc: &ArcLength, m: usize) -> Result<(), PlotError> {
    let e = draw_err(path);
    let (u0, u1) = c.u_range();
    let line: Vec<(f64, f64)> = (0..=2000)
        .map(|k| {
            let p = c.point(u0 + (u1 - u0) * k as f64 / 2000.0);
            (p[0], p[1])
        })
        .collect();
    let (mut x0, mut x1, mut y0, mut y1) =
        (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
    for &(x, y) in &line {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    let pad = 0.05 * (x1 - x0).max(y1 - y0).max(1e-6);
    png(path, (1200, 460), |root| {
        root.fill(&WHITE).map_err(&e)?;
        let root = root
            .titled(
                &format!("{}: sampling points, m = {m}", c.name),
                ("sans-serif", 24),
            )
            .map_err(&e)?;
        let panels = root.split_evenly((1, 3));
        for ((name, method), (panel, color)) in METHODS.iter().zip(panels.iter().zip(COLORS)) {
            let pts: Vec<(f64, f64)> = match sampling::sample(c, arc, *method, m) {
                Ok(s) => s
                    .iter()
                    .map(|&s| {
                        let p = c.point(arc.u_of_s(s));
                        (p[0], p[1])
                    })
                    .collect(),
                Err(_) => Vec::new(),
            };
            let mut ch = ChartBuilder::on(panel)
                .caption(*name, ("sans-serif", 20))
                .margin(8)
                .x_label_area_size(45)
                .y_label_area_size(60)
                .build_cartesian_2d((x0 - pad)..(x1 + pad), (y0 - pad)..(y1 + pad))
                .map_err(&e)?;
            ch.configure_mesh()
                .disable_mesh()
                .x_desc("x [mm]")
                .y_desc("y [mm]")
                .axis_desc_style(("sans-serif", 15))
                .label_style(("sans-serif", 13))
                .x_labels(5)
                .y_labels(5)
                .draw()
                .map_err(&e)?;
            ch.draw_series(LineSeries::new(
                line.iter().copied(),
                RGBColor(150, 150, 150).stroke_width(1),
            ))
            .map_err(&e)?;
            ch.draw_series(pts.iter().map(|&p| Circle::new(p, 3, color.filled())))
                .map_err(&e)?;
        }
        root.present().map_err(&e)?;
        Ok(())
    })
}

/// Simulated machining time against sampling density, per method and formulation.
pub(crate) fn fig_time(path: &Path, rep: &Report, cfg: &ReportConfig, curve: &str) -> Result<(), PlotError> {
    let e = draw_err(path);
    let mut series: Vec<(usize, usize, Series)> = Vec::new();
    for fi in 0..cfg.formulations.len() {
        for mi in 0..3 {
            let pts: Vec<(f64, f64)> = cfg
                .densities
                .iter()
                .filter_map(|&d| {
                    let c = rep.row(curve, d, mi, fi)?.outcome.as_ref().ok()?;
                    Some((d, sim_t(c)?))
                })
                .collect();
            series.push((fi, mi, pts));
        }
    }
    let all = || series.iter().flat_map(|s| s.2.iter().copied());
    let (d0, d1) = cfg
        .densities
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), &d| (a.min(d), b.max(d)));
    let (t0, t1) = all().fold((f64::INFINITY, 0.0f64), |(a, b), (_, t)| (a.min(t), b.max(t)));
    let (t0, t1) = if t0.is_finite() { (t0, t1) } else { (0.0, 1.0) };
    let span = (t1 - t0).max(1e-3 * t1.max(1e-9));
    png(path, (1000, 520), |root| {
        root.fill(&WHITE).map_err(&e)?;
        let title = format!("{curve}: simulated machining time against sampling density");
        let root = root
            .titled(&title, ("sans-serif", title_px(&title, 1000, 24)))
            .map_err(&e)?;
        let (left, right) = root.split_horizontally(1000 - 230);
        let mut ch = ChartBuilder::on(&left)
            .margin(15)
            .x_label_area_size(50)
            .y_label_area_size(70)
            .build_cartesian_2d(
                (d0 * 0.8).log10()..(d1 * 1.25).log10(),
                (t0 - 0.1 * span)..(t1 + 0.1 * span),
            )
            .map_err(&e)?;
        ch.configure_mesh()
            .x_desc("sampling density P [points/mm] (log scale)")
            .y_desc("simulated machining time T [s]")
            .x_label_formatter(&|x| format!("{:.2}", 10f64.powf(*x)))
            .axis_desc_style(("sans-serif", 18))
            .label_style(("sans-serif", 15))
            .light_line_style(RGBColor(235, 235, 235))
            .draw()
            .map_err(&e)?;
        let mut legend = Vec::new();
        for (fi, mi, pts) in &series {
            let color = COLORS[*mi];
            let line = Line::new(
                format!("{} {}", METHODS[*mi].0, cfg.formulations[*fi].name()),
                color,
                2,
                formulation_dash(*fi),
            );
            let lp: Vec<(f64, f64)> = pts.iter().map(|&(d, t)| (d.log10(), t)).collect();
            line.draw(&mut ch, lp.clone()).map_err(draw_err(path))?;
            ch.draw_series(lp.iter().map(|&p| Circle::new(p, 4, color.filled())))
                .map_err(&e)?;
            legend.push(line);
        }
        let (_, rh) = right.dim_in_pixel();
        let legend_area = right.margin(
            (rh / 2).saturating_sub(20 * legend.len() as u32 / 2 + 10),
            0,
            0,
            0,
        );
        draw_legend(&legend_area, &legend, 1, 15, 5).map_err(draw_err(path))?;
        root.present().map_err(&e)?;
        Ok(())
    })
}

/// Planned feed against arc length at the feed density, one panel per method.
pub(crate) fn fig_feed(path: &Path, rep: &Report, cfg: &ReportConfig, curve: &str) -> Result<(), PlotError> {
    let e = draw_err(path);
    let d = cfg.feed_density;
    png(path, (W, 760), |root| {
        root.fill(&WHITE).map_err(&e)?;
        let title = format!("{curve}: planned feed against arc length at {d} point/mm");
        let root = root
            .titled(&title, ("sans-serif", title_px(&title, W, 24)))
            .map_err(&e)?;
        let panels = root.split_evenly((3, 1));
        let lmax = rep.curves.iter().find(|c| c.0 == curve).map_or(1.0, |c| c.2);
        let vbar = cfg.limits.vbar;
        let vmax = vbar * 1.1;
        for (mi, panel) in panels.iter().enumerate() {
            let (chart_area, legend_area) = panel.split_horizontally(W - 250);
            let mut ch = ChartBuilder::on(&chart_area)
                .margin(8)
                .x_label_area_size(if mi == 2 { 45 } else { 25 })
                .y_label_area_size(65)
                .build_cartesian_2d(0.0..lmax, 0.0..vmax)
                .map_err(&e)?;
            ch.configure_mesh()
                .x_desc(if mi == 2 { "arc length s [mm]" } else { "" })
                .y_desc(format!("{}: feed [mm/s]", METHODS[mi].0))
                .axis_desc_style(("sans-serif", 15))
                .label_style(("sans-serif", 13))
                .light_line_style(RGBColor(235, 235, 235))
                .draw()
                .map_err(&e)?;
            let programmed = Line::new("programmed feed", BLACK, 1, Dash::Dashed(8, 5));
            programmed
                .draw(&mut ch, vec![(0.0, vbar), (lmax, vbar)])
                .map_err(draw_err(path))?;
            let mut legend = Vec::new();
            // the later formulations wide, light and dashed behind the first
            for fi in (0..cfg.formulations.len()).rev() {
                let Some(Ok(c)) = rep.row(curve, d, mi, fi).map(|r| &r.outcome) else {
                    continue;
                };
                let (color, width) = if fi == 0 {
                    (COLORS[mi], 2)
                } else {
                    (light(COLORS[mi]), 4)
                };
                let line = Line::new(
                    format!(
                        "{} {}: T = {}",
                        METHODS[mi].0,
                        cfg.formulations[fi].name(),
                        sim_t(c).map_or("—".into(), |t| format!("{t:.3} s"))
                    ),
                    color,
                    width,
                    formulation_dash(fi),
                );
                line.draw(&mut ch, c.feed.clone()).map_err(draw_err(path))?;
                legend.push(line);
            }
            legend.reverse();
            legend.push(programmed);
            let legend_area = legend_area.margin(20, 0, 0, 0);
            draw_legend(&legend_area, &legend, 1, 13, 5).map_err(draw_err(path))?;
        }
        root.present().map_err(&e)?;
        Ok(())
    })
}
