//! `feedplan`: plan a NURBS toolpath and write the firmware table.
//!
//! ```text
//! feedplan plan PART.ngc [--machine machine.toml | --limits FILE] [--density P] -o PART.bin [--json]
//! feedplan plan CURVE [--sampling par|len|ada] [--density P] [--limits FILE]
//!                     [--machine machine.toml] [--formulation certified|paper] [--ends jerk|step] [--period-us 250]
//!                     [--override-levels 30,50,125 | 10:200:10] -o TABLE.bin [--json]
//! feedplan override TABLE.bin --at S_MM --to PERCENT [--from PERCENT] [-o PROFILE.json] [--json]
//! feedplan parse PART.ngc [--json] [--block-delete]
//! feedplan completions bash|zsh|fish|elvish|powershell
//! ```
//!
//! CURVE is a JSON file or the name of a built-in curve. Exit codes: see
//! [`EXIT_CODES`].

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{CommandFactory, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use planner_host::feed_override::{OverrideContext, OverrideError, OverrideOutcome};
use planner_host::limits::LimitsError;
use planner_host::lp::{Objective, QhatBound};
use planner_host::plan::verify;
use planner_host::plan::{self, Formulation, PlanConfig, PlanError};
use planner_host::sampling::Sampling;
use planner_host::ArcLength;
use planner_host::CurveError;
use planner_host::EndMode;
use planner_host::Nurbs;

use planner_host::cli::{EXIT_CODES_HELP as EXIT_CODES, EXIT_INFEASIBLE, EXIT_INPUT, EXIT_IO, EXIT_USAGE};
use planner_host::outln;

#[derive(Parser)]
#[command(
    name = "feedplan",
    version,
    about = "Time-optimal jerk-limited feedrate planning on NURBS toolpaths (LP, Clarabel)",
    after_help = EXIT_CODES
)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Plan a toolpath and write the firmware table; or plan every path of a G-code program
    /// and write one program file (the tables in order, with their source lines).
    #[command(after_help = EXIT_CODES)]
    Plan {
        /// The toolpath: a JSON file (name, degree, weights, knots, control_points in mm), the
        /// name of a built-in curve (butterfly, circle, fan, star, trident), or a G-code program
        /// (.ngc, .nc, .tap, or any file that does not start with '{'): its tangent runs of moves
        /// become paths, each planned at min(F, the machine's feed) and rapids at the machine's
        /// rapid velocity, stopping at every corner (docs/gcode.md).
        curve: PathBuf,
        /// Machine file (machine.toml: per-axis and tangential limits, rapid velocity, servo
        /// period, travel); default the built-in Table 1 machine with ±1000 mm of travel.
        #[arg(long, conflicts_with = "limits")]
        machine: Option<PathBuf>,
        /// G-code program: skip the lines that start with '/' (block delete).
        #[arg(long)]
        block_delete: bool,
        /// G-code program: stop at every corner, as under G61, instead of fitting runs of G1
        /// chords under `G64 P` into smooth paths within the tolerance.
        #[arg(long)]
        exact_corners: bool,
        /// Sampling of the toolpath: par, len or ada (paper §3); a G-code program is sampled len.
        #[arg(long, default_value = "len")]
        sampling: Sampling,
        /// Sampling density, points per mm of arc length.
        #[arg(long, default_value_t = 1.0)]
        density: f64,
        /// Sampling density where the plan can cruise at the feed limit, points per mm (a curve
        /// sampled len, certified formulation): the samples kept only every DENSITY/CRUISE-th
        /// there, where no bend, curvature jump or end within a stop's distance needs a lower
        /// feed. Fewer columns for the LPs on long smooth paths, for a little machining time
        #[arg(long)]
        cruise_density: Option<f64>,
        /// Limits file (JSON: vbar, abar, jbar, v, a, j in mm and s); default the paper's Table 1.
        #[arg(long)]
        limits: Option<PathBuf>,
        /// Where to write the table.
        #[arg(short = 'o', long = "output")]
        output: PathBuf,
        /// Print the summary as one JSON object.
        #[arg(long)]
        json: bool,
        /// Formulation: certified (the default: limits held at check points in every span,
        /// jerk rows re-linearised in a trust region) or paper (§2.1: pseudo-jerk LP then
        /// plan LP at the Greville points; as printed unless --objective/--qhat-bound say otherwise).
        #[arg(long, default_value = "certified")]
        formulation: Formulation,
        /// Paper formulation: objective weights integral (c·a = ∫q ds, eq. 7) or uniform
        /// (c = 1, the default: the paper as printed).
        #[arg(long)]
        objective: Option<Objective>,
        /// Paper formulation: how the plan stays under the pseudo-jerk: control (a ≤ â),
        /// eval (q ≤ q̂ at the evaluation points) or none (the default: the paper as printed).
        #[arg(long)]
        qhat_bound: Option<QhatBound>,
        /// Certified formulation: check points per knot span of q.
        #[arg(long)]
        checks_per_span: Option<usize>,
        /// Start and stop: jerk (time-domain constant-jerk segments joined C² to q, at rest
        /// with zero acceleration at both ends) or step (q(0) = q(L) = 0, the paper: an
        /// acceleration step at both ends). Default: jerk with the certified formulation,
        /// step with the paper's.
        #[arg(long)]
        ends: Option<EndMode>,
        /// Servo period the table is planned for, µs: the feed at curvature jumps is
        /// capped so that the acceleration step uses at most half the jerk limit over
        /// one period (certified formulation). Default: the machine file's, else 250.
        #[arg(long)]
        period_us: Option<f64>,
        /// No progress bar (it is shown on stderr only when stderr is a terminal).
        #[arg(long, short = 'q')]
        quiet: bool,
        /// Points per knot span of q in the dense re-evaluation of the plan.
        #[arg(long, default_value_t = 20)]
        dense: usize,
        /// Feedrate override levels to plan into the table, percent of the programmed feed:
        /// a list (30,50,125) and/or ranges FROM:TO:STEP (10:200:10); 100 is the plan itself.
        /// Each level costs a whole plan and about 8·N + 60·(N−3) bytes of table
        /// (docs/override-design.md).
        #[arg(long, value_parser = parse_levels)]
        override_levels: Option<Levels>,
        /// Plan window by window (certified formulation): each window plans this much path
        /// ahead of what the windows before committed, joins it C² and comes to rest inside
        /// itself; mm.
        #[arg(long)]
        window_mm: Option<f64>,
        /// With --window-mm: path each window commits, mm (default a third of the window).
        #[arg(long, requires = "window_mm")]
        commit_mm: Option<f64>,
        /// With --window-mm: the first window shorter, WINDOW_MM:COMMIT_MM (the machine
        /// waits for it alone; its commit must reach past where a feed hold pressed while
        /// accelerating from rest comes to rest).
        #[arg(long, requires = "window_mm")]
        first_window: Option<planner_host::plan::FirstWindow>,
    },
    /// Compute one feedrate-override transition profile (paper §4) for inspection: the table's
    /// plan (or level --from) overridden at --at to level --to; the table must hold that level
    /// (feedplan plan --override-levels).
    #[command(after_help = EXIT_CODES)]
    Override {
        /// The firmware table (with override levels).
        table: PathBuf,
        /// Arc length of the override command, mm.
        #[arg(long)]
        at: f64,
        /// Target feed, percent of the programmed feed (a level of the table, or 100).
        #[arg(long)]
        to: f64,
        /// Active level, percent (default 100: the plan itself).
        #[arg(long, default_value_t = 100.0)]
        from: f64,
        /// Servo period, µs (feed caps at curvature jumps).
        #[arg(long, default_value_t = 250.0)]
        period_us: f64,
        /// Write the profile (the firmware message: level, first, ctrl; and the whole q) as JSON here.
        #[arg(short = 'o', long = "output")]
        output: Option<PathBuf>,
        /// Print the outcome as one JSON object (the profile, or why the override was skipped).
        #[arg(long)]
        json: bool,
    },
    /// Read a G-code part program (RS274/NGC as LinuxCNC reads it, 3 axes) and print its
    /// canonical moves: rapids, lines, arcs and NURBS in mm and mm/s, with the path-control mode
    /// of each; spindle, coolant and tool words are listed. What it refuses (cutter
    /// compensation, offsets, canned cycles, O-words, rotary axes…) exits 3 naming the line
    /// and the word (docs/gcode.md).
    #[command(after_help = EXIT_CODES)]
    Parse {
        /// The part program (.ngc).
        program: PathBuf,
        /// Print the program and its moves as one JSON object.
        #[arg(long)]
        json: bool,
        /// Skip the lines that start with '/' (the block-delete switch; off by default, as in
        /// LinuxCNC's rs274).
        #[arg(long)]
        block_delete: bool,
    },
    /// Print a shell completion script to stdout.
    Completions {
        /// The shell.
        shell: clap_complete::Shell,
    },
}

/// Override levels, percent.
#[derive(Debug, Clone)]
struct Levels(Vec<f64>);

/// `30,50,125`, `10:200:10` or a mixture; 100 dropped, duplicates refused
/// later by the planner's validation.
fn parse_levels(text: &str) -> Result<Levels, String> {
    let mut v = Vec::new();
    for part in text.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        let num = |x: &str| {
            x.trim()
                .parse::<f64>()
                .map_err(|_| format!("{x:?} is not a number (levels: 30,50,125 or FROM:TO:STEP)"))
        };
        let f: Vec<&str> = part.split(':').collect();
        match f.as_slice() {
            [x] => v.push(num(x)?),
            [a, b, st] => {
                let (a, b, st) = (num(a)?, num(b)?, num(st)?);
                // NaN fails both comparisons
                let ordered = st > 0.0 && b >= a;
                if !ordered || (b - a) / st > 1000.0 {
                    return Err(format!(
                        "range {part:?}: need FROM <= TO and STEP > 0 (at most 1000 levels)"
                    ));
                }
                let n = ((b - a) / st + 1e-9).floor() as usize;
                v.extend((0..=n).map(|k| a + st * k as f64));
            }
            _ => return Err(format!("{part:?}: expected a number or FROM:TO:STEP")),
        }
    }
    v.retain(|&p| p != 100.0);
    Ok(Levels(v))
}

/// A failure: the message and the exit code of [`EXIT_CODES`].
struct Failure {
    code: u8,
    message: String,
}

impl Failure {
    fn new(code: u8, message: impl std::fmt::Display) -> Self {
        Failure {
            code,
            message: message.to_string(),
        }
    }
}

impl From<CurveError> for Failure {
    fn from(e: CurveError) -> Self {
        Failure::new(EXIT_INPUT, e)
    }
}

impl From<LimitsError> for Failure {
    fn from(e: LimitsError) -> Self {
        Failure::new(EXIT_INPUT, e)
    }
}

impl From<serde_json::Error> for Failure {
    fn from(e: serde_json::Error) -> Self {
        Failure::new(EXIT_IO, e)
    }
}

impl From<PlanError> for Failure {
    fn from(e: PlanError) -> Self {
        Failure::new(planner_host::cli::plan_exit_code(&e), e)
    }
}

impl From<OverrideError> for Failure {
    fn from(e: OverrideError) -> Self {
        let code = match e {
            OverrideError::LpFailed { .. } => EXIT_INFEASIBLE,
            OverrideError::SOutOfRange { .. } => EXIT_USAGE,
            _ => EXIT_INPUT,
        };
        Failure::new(code, e)
    }
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(f) => {
            eprintln!("feedplan: error: {}", f.message);
            ExitCode::from(f.code)
        }
    }
}

/// One JSON object with `"schema_version": 1` as its first key, then the
/// keys of `v` (an object).
fn with_schema_version(v: &serde_json::Value) -> Result<String, Failure> {
    let body = serde_json::to_string(v)?;
    Ok(match body.strip_prefix('{') {
        Some("}") => "{\"schema_version\":1}".to_string(),
        Some(rest) => format!("{{\"schema_version\":1,{rest}"),
        None => return Err(Failure::new(EXIT_IO, "JSON output is not an object")),
    })
}

/// The curve argument (see [`planner_host::cli::load_curve`]).
fn load_curve(arg: &std::path::Path) -> Result<Nurbs, Failure> {
    planner_host::cli::load_curve(arg).map_err(|e| Failure::new(EXIT_INPUT, e))
}

/// A progress bar on stderr for the base plan and each override level,
/// drawn only when stderr is a terminal, not `quiet`, and the plan has run
/// for more than a second.
fn progress_bar(quiet: bool) -> ProgressBar {
    let pb = ProgressBar::with_draw_target(None, ProgressDrawTarget::hidden());
    if let Ok(style) = ProgressStyle::with_template("{elapsed:>4} [{bar:30}] {pos}/{len} {msg}") {
        pb.set_style(style.progress_chars("=> "));
    }
    if quiet {
        return pb;
    }
    let shown = pb.clone();
    std::thread::spawn(move || {
        std::thread::sleep(std::time::Duration::from_secs(1));
        if !shown.is_finished() {
            shown.set_draw_target(ProgressDrawTarget::stderr());
            shown.enable_steady_tick(std::time::Duration::from_millis(200));
        }
    });
    pb
}

fn run(cli: Cli) -> Result<(), Failure> {
    match cli.cmd {
        Cmd::Plan {
            curve,
            machine,
            block_delete,
            exact_corners,
            sampling,
            density,
            cruise_density,
            limits: lim_path,
            output,
            json,
            dense,
            formulation,
            objective,
            qhat_bound,
            checks_per_span,
            ends,
            period_us,
            quiet,
            override_levels,
            window_mm,
            commit_mm,
            first_window,
        } => {
            if formulation != Formulation::Paper && (objective.is_some() || qhat_bound.is_some()) {
                return Err(Failure::new(
                    EXIT_USAGE,
                    "--objective and --qhat-bound go with --formulation paper",
                ));
            }
            if let Some(c) = cruise_density.filter(|c| !(c.is_finite() && *c > 0.0)) {
                return Err(Failure::new(
                    EXIT_USAGE,
                    format!("--cruise-density {c}: must be a number > 0"),
                ));
            }
            let machine = planner_host::cli::load_machine(machine.as_deref(), lim_path.as_deref())
                .map_err(|e| Failure::new(e.exit_code(), e))?;
            if planner_host::cli::is_gcode_program(&curve) {
                if formulation != Formulation::Certified
                    || cruise_density.is_some()
                    || sampling != Sampling::Len
                    || override_levels.is_some()
                    || window_mm.is_some()
                    || ends.is_some()
                    || checks_per_span.is_some()
                    || period_us.is_some()
                {
                    return Err(Failure::new(
                        EXIT_USAGE,
                        "a G-code program is planned with the certified formulation, jerk-limited ends and the machine file's servo period: --formulation, --sampling, --cruise-density, --ends, --checks-per-span, --override-levels, --window-mm and --period-us go with a curve",
                    ));
                }
                let opts = planner_host::program::ProgramOptions {
                    density_per_mm: density,
                    fit_chords: !exact_corners,
                };
                return plan_program_cmd(&curve, &machine, &opts, block_delete, &output, json);
            }
            let curve = load_curve(&curve)?;
            let limits = machine.limits;
            let period_us = period_us.unwrap_or(machine.servo_period_s * 1e6);
            let mut cfg = PlanConfig {
                formulation,
                sampling,
                density_per_mm: density,
                cruise_density_per_mm: cruise_density,
                limits,
                objective: objective.unwrap_or(Objective::Uniform),
                qhat_bound: qhat_bound.unwrap_or(QhatBound::None),
                ends: ends.unwrap_or(match formulation {
                    Formulation::Paper => EndMode::Step,
                    Formulation::Certified => EndMode::Jerk,
                }),
                servo_period_s: period_us * 1e-6,
                override_levels: override_levels.map(|l| l.0).unwrap_or_default(),
                ..PlanConfig::default()
            };
            if let Some(c) = checks_per_span {
                cfg.certified.checks_per_span = c;
            }
            if let Some(w) = window_mm {
                let c = commit_mm.unwrap_or(w / 3.0);
                let wc = planner_host::plan::WindowConfig {
                    first: first_window,
                    ..planner_host::plan::WindowConfig::new(w, c)
                };
                if !wc.is_valid() || formulation != Formulation::Certified {
                    return Err(Failure::new(
                        EXIT_USAGE,
                        format!("--window-mm {w} --commit-mm {c}{}: a window must commit more than 0 and less than its length, with the certified formulation", first_window.map_or(String::new(), |f| format!(" --first-window {}:{}", f.window_mm, f.commit_mm))),
                    ));
                }
                cfg.windows = Some(wc);
            }
            let pb = progress_bar(quiet);
            pb.set_message(format!("planning {}", curve.name));
            let planned = plan::plan_curve_with_progress(&curve, &cfg, &|done, steps| {
                pb.set_length(steps as u64);
                pb.set_position(done as u64);
                pb.set_message(if done < steps {
                    format!("override level {done} of {}", steps - 1)
                } else {
                    "encoding the table".to_string()
                });
            });
            pb.finish_and_clear();
            let out = planned?;
            let arc = ArcLength::new(&curve);
            let check = verify::dense_check_ends(
                &curve,
                &arc,
                &out.q_knots,
                &out.q_ctrl,
                out.ends.as_ref(),
                &cfg.limits,
                cfg.feed_profile.as_ref(),
                dense,
            );
            let text = if json {
                let mut v = serde_json::to_value(&out)?;
                v["dense_check"] = serde_json::to_value(&check)?;
                v["table"] = serde_json::Value::String(output.display().to_string());
                with_schema_version(&v)?
            } else {
                format!(
                    "{}  table written to {}",
                    out.summary(Some(&check)),
                    output.display()
                )
            };
            plan::write_atomic(&output, &out.table_bytes)?;
            outln!("{text}");
            Ok(())
        }
        Cmd::Override {
            table,
            at,
            to,
            from,
            period_us,
            output,
            json,
        } => override_cmd(&table, at, from, to, period_us, output.as_deref(), json),
        Cmd::Parse {
            program,
            json,
            block_delete,
        } => parse_cmd(&program, json, block_delete),
        Cmd::Completions { shell } => {
            let mut script = Vec::new();
            clap_complete::generate(shell, &mut Cli::command(), "feedplan", &mut script);
            match std::io::Write::write_all(&mut std::io::stdout(), &script) {
                Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => Err(Failure::new(EXIT_IO, e)),
                _ => Ok(()),
            }
        }
    }
}

/// `feedplan plan PART.ngc`: every path planned, one program file written.
fn plan_program_cmd(
    path: &std::path::Path,
    machine: &planner_host::Machine,
    opts: &planner_host::program::ProgramOptions,
    block_delete: bool,
    output: &std::path::Path,
    json: bool,
) -> Result<(), Failure> {
    use planner_host::gcode;
    use planner_host::program::plan_program;
    let density = opts.density_per_mm;
    let bytes = std::fs::read(path)
        .map_err(|e| Failure::new(EXIT_INPUT, format!("cannot read {}: {e}", path.display())))?;
    let prog = gcode::read_bytes(&bytes, gcode::ReadOptions { block_delete })
        .map_err(|e| Failure::new(EXIT_INPUT, format!("{}: {e}", path.display())))?;
    if !(density.is_finite() && density > 0.0) {
        return Err(Failure::new(
            EXIT_USAGE,
            format!("--density {density}: must be a number > 0"),
        ));
    }
    let fail = |e: planner_host::program::ProgramError| {
        Failure::new(
            planner_host::cli::program_exit_code(&e),
            format!("{}: {e}", path.display()),
        )
    };
    let planned = plan_program(&prog, machine, opts).map_err(fail)?;
    let file = planned.encode().map_err(fail)?;
    let text = if json {
        let mut v = serde_json::to_value(&planned)?;
        v["program"] = path.display().to_string().into();
        v["output"] = output.display().to_string().into();
        v["output_bytes"] = file.len().into();
        with_schema_version(&v)?
    } else {
        format!(
            "{}: {}program file written to {} ({} bytes)",
            path.display(),
            planned.summary(),
            output.display(),
            file.len()
        )
    };
    plan::write_atomic(output, &file)?;
    outln!("{text}");
    Ok(())
}

/// `feedplan override`.
fn override_cmd(
    path: &std::path::Path,
    at: f64,
    from: f64,
    to: f64,
    period_us: f64,
    output: Option<&std::path::Path>,
    json: bool,
) -> Result<(), Failure> {
    let bytes = std::fs::read(path)
        .map_err(|e| Failure::new(EXIT_INPUT, format!("cannot read {}: {e}", path.display())))?;
    let table = firmware_core::Table::parse(&bytes)
        .map_err(|e| Failure::new(EXIT_INPUT, format!("{}: table refused: {e:?}", path.display())))?;
    let ctx = OverrideContext::from_table(&table, period_us * 1e-6)?;
    let id_of = |pct: f64| -> Result<u16, Failure> {
        (0..ctx.level_count() as u16)
            .find(|&id| ctx.level_percent(id).is_some_and(|p| (p - pct).abs() < 1e-9))
            .ok_or_else(|| {
                let have: Vec<String> = (0..ctx.level_count() as u16)
                    .filter_map(|id| ctx.level_percent(id).map(|p| format!("{p}")))
                    .collect();
                Failure::new(
                    EXIT_INPUT,
                    format!(
                        "no {pct} % level in {} (it has {} %)",
                        path.display(),
                        have.join(", ")
                    ),
                )
            })
    };
    let (a, t) = (id_of(from)?, id_of(to)?);
    let active = ctx
        .level_ctrl(a)
        .ok_or_else(|| Failure::new(EXIT_INPUT, "no active level"))?
        .to_vec();
    match ctx.compute(a, &active, at, t)? {
        OverrideOutcome::Skip(why) => {
            if json {
                let v = serde_json::json!({
                    "outcome": "skipped",
                    "skip_reason": format!("{why:?}"),
                    "at_s_mm": at,
                    "percent": to,
                    "from_percent": from,
                });
                outln!("{}", with_schema_version(&v)?);
            } else {
                outln!("override at s = {at} mm from {from} % to {to} %: skipped ({why:?}); the active profile stays");
            }
        }
        OverrideOutcome::Profile(p) => {
            let v = serde_json::json!({
                "level": p.level,
                "percent": to,
                "from_percent": from,
                "first": p.first,
                "ctrl": p.ctrl,
                "splice_s_mm": p.splice_s_mm,
                "merge_s_mm": p.merge_s_mm,
                "case": format!("{:?}", p.case),
                "transition_len_mm": p.transition_len_mm,
                "arclen_estimate_mm": p.arclen_estimate_mm,
                "retries_grow": p.retries_grow,
                "retries_extreme": p.retries_extreme,
                "override_s_mm": p.override_s_mm,
                "q_knots": ctx.knots(),
                "q_ctrl": p.full_ctrl,
            });
            if let Some(out) = output {
                plan::write_atomic(out, serde_json::to_string_pretty(&v)?.as_bytes())?;
            }
            if json {
                let mut o = v.clone();
                o["outcome"] = "profile".into();
                o["at_s_mm"] = at.into();
                o["lp_count"] = p.lp_count.into();
                o["compute_time_s"] = p.compute_time_s.into();
                if let Some(out) = output {
                    o["profile_file"] = out.display().to_string().into();
                }
                outln!("{}", with_schema_version(&o)?);
                return Ok(());
            }
            outln!(
                "override at s = {at} mm from {from} % to {to} %: {:?}\n  splice s = {:.4} mm (first changed span {}), merge s = {:.4} mm\n  \
                 transition {:.3} mm (ArcLen estimate {}), {} new control points, {} LPs, retries {} (window) + {} (Algorithm 2)\n  \
                 override point used {:.4} mm, computed in {:.2} ms",
                p.case,
                p.splice_s_mm,
                p.first,
                p.merge_s_mm,
                p.transition_len_mm,
                p.arclen_estimate_mm.map_or("-".into(), |x| format!("{x:.3} mm")),
                p.ctrl.len().saturating_sub(3),
                p.lp_count,
                p.retries_grow,
                p.retries_extreme,
                p.override_s_mm,
                p.compute_time_s * 1e3
            );
            if let Some(out) = output {
                outln!("  profile written to {}", out.display());
            }
        }
    }
    Ok(())
}

/// `feedplan parse`.
fn parse_cmd(path: &std::path::Path, json: bool, block_delete: bool) -> Result<(), Failure> {
    use planner_host::gcode::{self, MoveKind, NoteWord};
    let bytes = std::fs::read(path)
        .map_err(|e| Failure::new(EXIT_INPUT, format!("cannot read {}: {e}", path.display())))?;
    let prog = gcode::read_bytes(&bytes, gcode::ReadOptions { block_delete })
        .map_err(|e| Failure::new(EXIT_INPUT, format!("{}: {e}", path.display())))?;
    let kinds = [
        ("rapid", MoveKind::Rapid),
        ("line", MoveKind::Line),
        ("arc", MoveKind::Arc),
        ("nurbs", MoveKind::Nurbs),
    ];
    if json {
        let mut v = serde_json::to_value(&prog)?;
        v["program"] = path.display().to_string().into();
        let counts: serde_json::Map<String, serde_json::Value> = kinds
            .iter()
            .map(|(name, k)| (name.to_string(), prog.count(*k).into()))
            .collect();
        v["counts"] = counts.into();
        outln!("{}", with_schema_version(&v)?);
        return Ok(());
    }
    let by_kind: Vec<String> = kinds
        .iter()
        .map(|(name, k)| format!("{name} {}", prog.count(*k)))
        .collect();
    outln!(
        "{}: {} lines, {} blocks, {} moves ({})",
        path.display(),
        prog.lines,
        prog.blocks,
        prog.moves.len(),
        by_kind.join(", ")
    );
    if let Some(first) = prog.moves.first() {
        let (mut lo, mut hi) = (first.start, first.start);
        for m in &prog.moves {
            for k in 0..3 {
                lo[k] = lo[k].min(m.end[k]);
                hi[k] = hi[k].max(m.end[k]);
            }
        }
        outln!(
            "  end points within X {:.3} .. {:.3}, Y {:.3} .. {:.3}, Z {:.3} .. {:.3} mm",
            lo[0],
            hi[0],
            lo[1],
            hi[1],
            lo[2],
            hi[2]
        );
        let feeds: Vec<f64> = prog.moves.iter().filter_map(|m| m.feed_mm_s).collect();
        if let (Some(fmin), Some(fmax)) = (
            feeds.iter().copied().reduce(f64::min),
            feeds.iter().copied().reduce(f64::max),
        ) {
            outln!("  feed {:.1} .. {:.1} mm/min", fmin * 60.0, fmax * 60.0);
        }
    }
    let list = |name: &str, words: &[NoteWord]| {
        if words.is_empty() {
            outln!("  {name}: none");
        } else {
            let w: Vec<String> = words
                .iter()
                .map(|n| format!("{} (line {})", n.word, n.line))
                .collect();
            outln!("  {name}: {}", w.join(", "));
        }
    };
    list("spindle", &prog.spindle);
    list("coolant", &prog.coolant);
    list("tool", &prog.tool);
    list("program control", &prog.program_control);
    for w in &prog.warnings {
        outln!("  warning: {w}");
    }
    Ok(())
}
