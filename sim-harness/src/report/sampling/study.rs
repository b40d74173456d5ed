//! The study end to end: [`run_report`] loads the curves, runs every case
//! and the q̂ analysis (with a progress bar), draws the figures and writes
//! the Markdown report.

use std::time::Instant;

use planner_host::ArcLength;
use planner_host::Nurbs;

use crate::plot::png::register_font;
use crate::report::sampling::config::{ReportConfig, ReportError, METHODS};
use crate::report::sampling::figures::{fig_feed, fig_sampling, fig_time};
use crate::report::sampling::markdown::markdown;
use crate::report::sampling::qhat::diagnose;
use crate::report::sampling::results::{file_stem, Report, Row};
use crate::report::sampling::runs::run_case;

/// Run the study and write `cfg.out/README.md` and the figures.
pub fn run_report(cfg: &ReportConfig) -> Result<Report, ReportError> {
    let t0 = Instant::now();
    if cfg.densities.is_empty() || cfg.densities.iter().any(|d| !(d.is_finite() && *d > 0.0)) {
        return Err(ReportError::Config(format!(
            "densities must be positive numbers, got {:?}",
            cfg.densities
        )));
    }
    if cfg.formulations.is_empty() {
        return Err(ReportError::Config("no formulation given".into()));
    }
    std::fs::create_dir_all(&cfg.out).map_err(|source| ReportError::Io {
        path: cfg.out.display().to_string(),
        source,
    })?;
    let mut rep = Report::default();
    let mut loaded = Vec::new();
    for path in &cfg.curves {
        match Nurbs::load(path).and_then(|c| c.validate().map(|()| c)) {
            Ok(c) => {
                let arc = ArcLength::new(&c);
                rep.curves
                    .push((c.name.clone(), path.display().to_string(), arc.total()));
                loaded.push((c, arc));
            }
            Err(e) => rep.curve_errors.push((path.display().to_string(), e.to_string())),
        }
    }
    let per_curve = cfg.densities.len() * METHODS.len() * cfg.formulations.len()
        + if cfg.decomposition { METHODS.len() } else { 0 };
    let bar = if cfg.progress {
        let b = indicatif::ProgressBar::new((per_curve * loaded.len()) as u64);
        b.set_style(
            indicatif::ProgressStyle::with_template("{elapsed_precise} [{bar:40}] {pos}/{len} {msg}")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
                .progress_chars("=> "),
        );
        b
    } else {
        indicatif::ProgressBar::hidden()
    };
    for (c, arc) in &loaded {
        for &density in &cfg.densities {
            for (mi, (mname, method)) in METHODS.iter().enumerate() {
                for (fi, &f) in cfg.formulations.iter().enumerate() {
                    bar.set_message(format!("{} {density}/mm {mname} {}", c.name, f.name()));
                    rep.rows.push(Row {
                        curve: c.name.clone(),
                        density,
                        method: mi,
                        formulation: fi,
                        outcome: run_case(c, arc, cfg, *method, density, f),
                    });
                    bar.inc(1);
                }
            }
        }
        if cfg.decomposition {
            let mut v = Vec::new();
            for (mname, method) in METHODS {
                bar.set_message(format!("{} q̂ analysis {mname}", c.name));
                v.push(diagnose(c, cfg, method));
                bar.inc(1);
            }
            rep.diag.push((c.name.clone(), v));
        }
    }
    bar.finish_and_clear();

    // figures
    register_font()?;
    for (c, arc) in &loaded {
        let stem = file_stem(&c.name);
        let p = cfg.out.join(format!("{stem}_sampling.png"));
        fig_sampling(&p, c, arc, cfg.figure_points)?;
        rep.files.push(p);
        let p = cfg.out.join(format!("{stem}_time.png"));
        fig_time(&p, &rep, cfg, &c.name)?;
        rep.files.push(p);
        if cfg.densities.contains(&cfg.feed_density) {
            let p = cfg.out.join(format!("{stem}_feed.png"));
            fig_feed(&p, &rep, cfg, &c.name)?;
            rep.files.push(p);
        }
    }
    rep.wall_s = t0.elapsed().as_secs_f64();
    let md = markdown(&rep, cfg);
    let readme = cfg.out.join("README.md");
    crate::csv::write_atomic(&readme, md.as_bytes()).map_err(|e| ReportError::Io {
        path: readme.display().to_string(),
        source: std::io::Error::other(e.to_string()),
    })?;
    rep.files.push(readme);
    Ok(rep)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn report_on_one_short_curve() {
        let dir = std::env::temp_dir().join(format!("feedsim-report-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let curve = dir.join("small.json");
        let mut c = Nurbs::circle([0.0; 3], 5.0);
        c.name = "Small circle".into();
        std::fs::write(&curve, curve_json(&c)).unwrap();
        let missing = dir.join("missing.json");
        let out = dir.join("report");
        let cfg = ReportConfig {
            curves: vec![curve, missing],
            densities: vec![1.0],
            out: out.clone(),
            progress: false,
            command: "feedsim report small.json --densities 1".into(),
            ..ReportConfig::default()
        };
        let rep = run_report(&cfg).unwrap();
        assert_eq!(rep.curves.len(), 1);
        assert_eq!(rep.curve_errors.len(), 1);
        assert_eq!(rep.rows.len(), 3 * cfg.formulations.len());
        let md = std::fs::read_to_string(out.join("README.md")).unwrap();
        assert!(md.contains("    feedsim report small.json --densities 1"), "{md}");
        assert!(md.contains("| curve | P /mm | m | PAR | LEN | ADA | PAR vs ADA | LEN vs ADA |"));
        // one machining-time row per formulation, one LP row per method and formulation
        assert_eq!(
            md.matches("| Small circle | 1 | 31 |").count(),
            cfg.formulations.len(),
            "{md}"
        );
        for m in ["PAR", "LEN", "ADA"] {
            assert_eq!(
                md.matches(&format!("| Small circle | 1 | {m} |")).count(),
                cfg.formulations.len(),
                "{md}"
            );
        }
        assert!(md.contains("missing.json"));
        for f in [
            "small_circle_sampling.png",
            "small_circle_time.png",
            "small_circle_feed.png",
        ] {
            let bytes = std::fs::read(out.join(f)).unwrap();
            assert!(bytes.len() > 1000, "{f}: {} bytes", bytes.len());
            assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
            assert!(md.contains(f));
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    fn curve_json(c: &Nurbs) -> String {
        serde_json::json!({
            "name": c.name,
            "degree": c.degree,
            "knots": c.knots,
            "weights": c.weights,
            "control_points": c.points,
        })
        .to_string()
    }
}
