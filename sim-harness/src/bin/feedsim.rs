//! `feedsim`: run a firmware table through the interpolator and simulated
//! servos, and measure the motion.
//!
//! ```text
//! feedsim run TABLE.bin [--period-us 250] [--csv OUT.csv] [--plot OUT.png] [--json] [--servo FILE]
//! feedsim demo [--out DIR]
//! feedsim report [CURVES...] [--densities 0.25,0.5,1,2] [--out DIR] [--formulations paper,default] [--qhat-bound B] [--objective O]
//! ```

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use planner_host::plan::{self, PlanConfig};
use planner_host::ArcLength;
use planner_host::{builtin, limits, plan::verify, sampling::Sampling};
use sim_harness::plot::{self, FeedPlot};
use sim_harness::servo::ServoConfig;
use sim_harness::sim::{self, SimConfig, SimResult};

#[derive(Parser)]
#[command(
    name = "feedsim",
    version,
    about = "Run a feedrate table through firmware-core's interpolator and simulated servos; measure the motion"
)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Simulate a table: machining time, ratios to the limits, contour and following error, feed fluctuation.
    Run {
        /// The firmware table (feedplan's output).
        table: PathBuf,
        /// Servo period, microseconds.
        #[arg(long, default_value_t = 250.0)]
        period_us: f64,
        /// Write one CSV row per servo tick here (t,x,y,z,s,u,feed,ax,ay,az).
        #[arg(long)]
        csv: Option<PathBuf>,
        /// Write the feedrate plot (PNG) here.
        #[arg(long)]
        plot: Option<PathBuf>,
        /// Print one JSON object instead of the text summary.
        #[arg(long)]
        json: bool,
        /// Servo model: JSON, one object for all axes or an array of 3 (x, y, z); fields as in
        /// sim-harness/servo.example.json, missing ones keep the defaults.
        #[arg(long)]
        servo: Option<PathBuf>,
    },
    /// Plan the built-in Butterfly (Table 1 limits, LEN sampling, 1 point/mm), simulate it at 250 us,
    /// write DIR/butterfly.bin, DIR/butterfly.csv and DIR/butterfly_feed.png.
    Demo {
        /// Output directory (created if missing).
        #[arg(long, default_value = "out")]
        out: PathBuf,
    },
    /// The sampling study: plan every curve at every density with PAR, LEN and ADA, simulate each,
    /// and write DIR/README.md (Markdown tables) and PNG figures.
    Report {
        /// Curve JSON files (default: every *.json in ../shared/curves).
        curves: Vec<PathBuf>,
        /// Sampling densities, points per mm, comma-separated.
        #[arg(long, value_delimiter = ',', default_value = "0.25,0.5,1,2")]
        densities: Vec<f64>,
        /// Output directory.
        #[arg(long, default_value = "docs/sampling")]
        out: PathBuf,
        /// Formulations, comma-separated: paper (q-hat bound none, uniform weights), default
        /// (control, integral) or BOUND/OBJECTIVE; the first is the solid line of the figures.
        #[arg(long, value_delimiter = ',', default_value = "paper,default")]
        formulations: Vec<sim_harness::report::Formulation>,
        /// Replace the formulations by these q-hat bounds (control, eval, none; comma-separated),
        /// combined with --objective (default integral).
        #[arg(long, value_delimiter = ',')]
        qhat_bound: Vec<planner_host::lp::QhatBound>,
        /// Objective weights for --qhat-bound: integral or uniform.
        #[arg(long)]
        objective: Option<planner_host::lp::Objective>,
        /// Limits file (JSON); default the paper's Table 1.
        #[arg(long)]
        limits: Option<PathBuf>,
        /// Servo period, microseconds.
        #[arg(long, default_value_t = 250.0)]
        period_us: f64,
        /// Skip the q-hat bound x objective analysis.
        #[arg(long)]
        no_decomposition: bool,
        /// No progress bar.
        #[arg(long)]
        quiet: bool,
    },
    /// Override scenarios (issue 6): the paper's Figs 13-15, an override storm, feed holds and link
    /// faults, each planned with its override levels and simulated with a host-firmware link model;
    /// writes DIR/README.md, a CSV and a feed plot per scenario.
    Override {
        /// Scenarios (default all): fig13, fig14, fig15, storm, holds, faults.
        scenarios: Vec<String>,
        /// Output directory.
        #[arg(long, default_value = "docs/override")]
        out: PathBuf,
        /// One-way link latency host <-> firmware, milliseconds.
        #[arg(long, default_value_t = 5.0)]
        latency_ms: f64,
        /// Host compute budget in the timeline, milliseconds (measured times are reported beside it).
        #[arg(long, default_value_t = 10.0)]
        compute_ms: f64,
        /// The Fig. 15 curve (default ../shared/curves/trident.json).
        #[arg(long)]
        trident: Option<PathBuf>,
        /// Servo period, microseconds.
        #[arg(long, default_value_t = 250.0)]
        period_us: f64,
    },
}

type BoxError = Box<dyn std::error::Error>;

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("feedsim: error: {e}");
            ExitCode::from(2)
        }
    }
}

fn run(cli: Cli) -> Result<(), BoxError> {
    match cli.cmd {
        Cmd::Run {
            table,
            period_us,
            csv,
            plot,
            json,
            servo,
        } => {
            if !(period_us.is_finite() && period_us > 0.0) {
                return Err(format!("--period-us must be a positive number, got {period_us}").into());
            }
            let mut cfg = SimConfig {
                period_s: period_us * 1e-6,
                ..SimConfig::default()
            };
            if let Some(path) = servo {
                cfg.servo = ServoConfig::load_axes(&path)?;
            }
            let bytes = std::fs::read(&table).map_err(|e| format!("cannot read {}: {e}", table.display()))?;
            let res = sim::run_table(&bytes, &cfg).map_err(|e| format!("{}: {e}", table.display()))?;
            if let Some(path) = &csv {
                sim_harness::csv::write_csv(path, &res.ticks)?;
            }
            let title = table
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            if let Some(path) = &plot {
                write_plot(path, &res, &title)?;
            }
            if json {
                let mut v = serde_json::to_value(res.summary_json())?;
                v["table"] = table.display().to_string().into();
                if let Some(p) = &csv {
                    v["csv"] = p.display().to_string().into();
                }
                if let Some(p) = &plot {
                    v["plot"] = p.display().to_string().into();
                }
                println!("{}", serde_json::to_string(&v)?);
            } else {
                println!("{}", table.display());
                print!("{}", res.summary());
                if let Some(p) = &csv {
                    println!("  wrote {}", p.display());
                }
                if let Some(p) = &plot {
                    println!("  wrote {}", p.display());
                }
            }
            Ok(())
        }
        Cmd::Demo { out } => demo(&out),
        Cmd::Override {
            scenarios,
            out,
            latency_ms,
            compute_ms,
            trident,
            period_us,
        } => override_report(&scenarios, &out, latency_ms, compute_ms, trident, period_us),
        Cmd::Report {
            curves,
            densities,
            out,
            formulations,
            qhat_bound,
            objective,
            limits: limits_file,
            period_us,
            no_decomposition,
            quiet,
        } => {
            use sim_harness::report::{self, Formulation, ReportConfig};
            if !(period_us.is_finite() && period_us > 0.0) {
                return Err(format!("--period-us must be a positive number, got {period_us}").into());
            }
            let curves = if curves.is_empty() {
                default_curves()?
            } else {
                curves
            };
            let formulations = if qhat_bound.is_empty() {
                if objective.is_some() {
                    return Err(
                        "--objective goes with --qhat-bound (or use --formulations BOUND/OBJECTIVE)".into(),
                    );
                }
                formulations
            } else {
                qhat_bound
                    .into_iter()
                    .map(|b| Formulation {
                        qhat_bound: b,
                        objective: objective.unwrap_or_default(),
                    })
                    .collect()
            };
            let lim = match &limits_file {
                Some(p) => limits::load(p)?,
                None => limits::TABLE1,
            };
            let cfg = ReportConfig {
                curves,
                densities,
                out: out.clone(),
                formulations,
                limits: lim,
                sim: SimConfig {
                    period_s: period_us * 1e-6,
                    ..SimConfig::default()
                },
                decomposition: !no_decomposition,
                progress: !quiet,
                command: std::iter::once("cargo run --release -p sim-harness --bin feedsim --".to_string())
                    .chain(std::env::args().skip(1))
                    .collect::<Vec<_>>()
                    .join(" "),
                ..ReportConfig::default()
            };
            let rep = report::run_report(&cfg)?;
            let failed = rep.rows.iter().filter(|r| r.outcome.is_err()).count();
            println!(
                "wrote {} ({} files) in {:.1} s: {} curves, {} cases, {} without a plan",
                out.join("README.md").display(),
                rep.files.len(),
                rep.wall_s,
                rep.curves.len(),
                rep.rows.len(),
                failed
            );
            for (p, e) in &rep.curve_errors {
                eprintln!("feedsim: {p}: {e}");
            }
            Ok(())
        }
    }
}

/// Every `*.json` in `../shared/curves` (relative to the working directory), sorted.
fn default_curves() -> Result<Vec<PathBuf>, BoxError> {
    let dir = Path::new("../shared/curves");
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| format!("cannot list {}: {e} (name the curves instead)", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "json"))
        .collect();
    v.sort();
    if v.is_empty() {
        return Err(format!("no *.json curves in {}", dir.display()).into());
    }
    Ok(v)
}

fn write_plot(path: &Path, res: &SimResult, name: &str) -> Result<(), BoxError> {
    let (commanded, actual) = res.simulated_feed();
    let title = format!(
        "{name}: feed against arc length (T = {:.4} s simulated, {:.4} s predicted)",
        res.metrics.machining_time_s, res.predicted_time_s
    );
    plot::plot_feed(
        path,
        &FeedPlot {
            title: &title,
            planned: &res.planned_feed,
            commanded: &commanded,
            actual: Some(&actual),
            vbar_mm_s: Some(res.limits.vbar),
            extra: &[],
        },
    )?;
    Ok(())
}

fn demo(out: &Path) -> Result<(), BoxError> {
    std::fs::create_dir_all(out).map_err(|e| format!("cannot create {}: {e}", out.display()))?;
    let curve = builtin::butterfly()?;
    let cfg = PlanConfig {
        sampling: Sampling::Len,
        density_per_mm: 1.0,
        limits: limits::TABLE1,
        ..PlanConfig::default()
    };
    let planned = plan::plan_curve(&curve, &cfg)?;
    let arc = ArcLength::new(&curve);
    let check = verify::dense_check_ends(
        &curve,
        &arc,
        &planned.q_knots,
        &planned.q_ctrl,
        planned.ends.as_ref(),
        &cfg.limits,
        20,
    );
    println!("== plan");
    print!("{}", planned.summary(Some(&check)));

    let bin = out.join("butterfly.bin");
    sim_harness::csv::write_atomic(&bin, &planned.table_bytes)?;
    let res = sim::run_table(&planned.table_bytes, &SimConfig::default())?;
    println!("== simulation");
    print!("{}", res.summary());
    let csv = out.join("butterfly.csv");
    sim_harness::csv::write_csv(&csv, &res.ticks)?;
    let png = out.join("butterfly_feed.png");
    write_plot(&png, &res, "Butterfly")?;
    println!("== wrote {}, {}, {}", bin.display(), csv.display(), png.display());
    Ok(())
}

fn override_report(
    names: &[String],
    out: &Path,
    latency_ms: f64,
    compute_ms: f64,
    trident: Option<PathBuf>,
    period_us: f64,
) -> Result<(), BoxError> {
    use sim_harness::override_report as orep;
    std::fs::create_dir_all(out).map_err(|e| format!("cannot create {}: {e}", out.display()))?;
    let butterfly = builtin::butterfly()?;
    let trident_path = trident.unwrap_or_else(|| PathBuf::from("../shared/curves/trident.json"));
    let trident = planner_host::Nurbs::load(&trident_path).ok();
    let link = sim_harness::scenario::LinkConfig {
        down_latency_s: latency_ms * 1e-3,
        up_latency_s: latency_ms * 1e-3,
        compute_budget_s: compute_ms * 1e-3,
        ..Default::default()
    };
    let all = orep::catalogue(&butterfly, trident.as_ref(), link);
    for n in names {
        if !all.iter().any(|s| s.name == n) {
            return Err(format!(
                "unknown scenario {n:?} (known: {})",
                all.iter().map(|s| s.name).collect::<Vec<_>>().join(", ")
            )
            .into());
        }
    }
    let mut md = format!(
        "# Feedrate override and feed hold scenarios\n\nMade by `cargo run --release -p sim-harness --bin feedsim -- override{}` \
         (one-way link latency {latency_ms} ms, host compute budget {compute_ms} ms in the timeline, servo period {period_us} us). \
         Ratios are the commanded setpoints' largest ratio to each limit with the machine at rest before and after \
         (`--pad-rest`), by feedsim's own stencils; `.ci/check-traj.sh` runs `shared/checks/check_traj.py --pad-rest 50` on the CSVs.\n\n{}\n",
        names.iter().map(|n| format!(" {n}")).collect::<String>(),
        orep::TABLE_HEAD
    );
    let mut notes = String::new();
    for spec in all
        .iter()
        .filter(|s| names.is_empty() || names.iter().any(|n| n == s.name))
    {
        eprintln!("feedsim override: {} ...", spec.name);
        let run = orep::run_spec(spec, period_us * 1e-6)?;
        let (row, files) = orep::write_run(out, &run)?;
        println!("{row}");
        md.push_str(&row);
        md.push('\n');
        let jitter = if spec.jitter.isr_latency_frac > 0.0 {
            format!(
                " Tick interrupt latency up to {:.0} us drawn per tick (largest {:.1} us); {} downlink message(s) reached the firmware one tick earlier for it.",
                spec.jitter.isr_latency_frac * period_us,
                run.result.max_isr_latency_s * 1e6,
                run.result.shifted_by_jitter
            )
        } else {
            String::new()
        };
        notes.push_str(&format!(
            "- **{}**: {}.{jitter} Plan with {} level(s) {:.2} s, override context {:.1} ms; files {}.\n",
            spec.name,
            spec.what,
            spec.levels.len(),
            run.plan_time_s,
            run.context_time_s * 1e3,
            files
                .iter()
                .filter_map(|f| f.file_name().map(|n| format!("`{}`", n.to_string_lossy())))
                .collect::<Vec<_>>()
                .join(", ")
        ));
        let h = &run.result.holds;
        if !h.is_empty() {
            let dist: Vec<f64> = h
                .iter()
                .filter_map(|r| Some(r.s_stopped_mm? - r.s_hold_mm))
                .collect();
            let time: Vec<f64> = h
                .iter()
                .filter_map(|r| Some(r.t_stopped_s? - r.t_hold_s))
                .collect();
            notes.push_str(&format!(
                "  Holds: {} pressed, {} came to rest (the others were resumed while stopping); hold to rest {} mm and {} s (median / max); `{}_holds.json`.\n",
                h.len(),
                dist.len(),
                sim_harness::scenario::median_max(&dist).map_or("–".into(), |(a, b)| format!("{a:.1} / {b:.1}")),
                sim_harness::scenario::median_max(&time).map_or("–".into(), |(a, b)| format!("{a:.2} / {b:.2}")),
                spec.name
            ));
            sim_harness::csv::write_atomic(
                &out.join(format!("{}_holds.json", spec.name)),
                serde_json::to_string_pretty(h)?.as_bytes(),
            )?;
        }
        let json = serde_json::to_string_pretty(&run.result.overrides)?;
        sim_harness::csv::write_atomic(
            &out.join(format!("{}_overrides.json", spec.name)),
            json.as_bytes(),
        )?;
    }
    md.push('\n');
    md.push_str(&notes);
    sim_harness::csv::write_atomic(&out.join("README.md"), md.as_bytes())?;
    println!("wrote {}", out.join("README.md").display());
    Ok(())
}
