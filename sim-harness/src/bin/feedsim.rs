//! `feedsim`: run a firmware table through the interpolator and simulated
//! servos, measure the motion, and check setpoints against every limit.
//!
//! ```text
//! feedsim run PART.bin [--machine machine.toml] [--csv OUT.csv] [--plot OUT.png] [--check [--tol 0.005]]
//! feedsim run TABLE.bin [--period-us 250] [--csv OUT.csv] [--plot OUT.png] [--json] [--servo FILE]
//!                       [--check [--tol 0.005] [--pad-rest 50]]
//! feedsim check OUT.csv --curve CURVE [--limits FILE] [--pad-rest 50] [--tol 0.005] [--contour-tol 1e-3] [--json]
//! feedsim demo [--out DIR]
//! feedsim report [CURVES...] [--densities 0.25,0.5,1,2] [--out DIR] [--formulations paper,default] [--qhat-bound B] [--objective O]
//! feedsim override [SCENARIOS...] [--latency-ms 5] [--out DIR]
//! feedsim stream CURVE [--link uart:BAUD] [--latency-ms 5] [--ring-bytes 16384] [--chunk-mm 32]
//!                      [--window-mm 200 --commit-mm 150 | --whole] [--stall T:D]... [--override T:PCT]...
//!                      [--faults corrupt:N,drop:N,duplicate:N,reorder:N,restart:S]
//!                      [--u-form] [--tol 0.01] [--json]
//! feedsim completions SHELL
//! ```

use std::fmt::Display;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{CommandFactory, Parser, Subcommand};
use planner_host::plan::{self, PlanConfig, PlanError};
use planner_host::ArcLength;
use planner_host::Nurbs;
use planner_host::{limits, plan::verify, sampling::Sampling};
use sim_harness::check::{self, CheckConfig, CheckReport, Trajectory};
use sim_harness::plot::{self, FeedPlot};
use sim_harness::servo::ServoConfig;
use sim_harness::{run_table, SimConfig, SimError, SimResult};

use planner_host::cli::{EXIT_CODES_HELP as EXIT_CODES, EXIT_INPUT, EXIT_IO, EXIT_LIMIT};
use planner_host::{out, outln};

#[derive(Parser)]
#[command(
    name = "feedsim",
    version,
    about = "Run a feedrate table through firmware-core's interpolator and simulated servos; measure the motion and check it against every limit",
    after_help = EXIT_CODES
)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Simulate a table: machining time, ratios to the limits, contour and following error, feed
    /// fluctuation. A program file (feedplan plan PART.ngc) runs every path in order, each from
    /// rest where the previous one stopped; the CSV then has path and block (source line) columns.
    #[command(after_help = EXIT_CODES)]
    Run {
        /// The firmware table or program file (feedplan's output).
        table: PathBuf,
        /// Servo period, microseconds (default: the machine file's; for a program file, the period
        /// its tables were planned for; else 250).
        #[arg(long)]
        period_us: Option<f64>,
        /// Machine file (machine.toml): its servo period; default the built-in Table 1 machine.
        #[arg(long)]
        machine: Option<PathBuf>,
        /// Write one CSV row per servo tick here (t,x,y,z,s,u,feed,ax,ay,az; a program adds
        /// path,block).
        #[arg(long)]
        csv: Option<PathBuf>,
        /// Write the feedrate plot (PNG) here (a program file: its toolpath, XY, coloured by feed).
        #[arg(long)]
        plot: Option<PathBuf>,
        /// Print one JSON object instead of the text summary.
        #[arg(long)]
        json: bool,
        /// Servo model: JSON, one object for all axes or an array of 3 (x, y, z); fields as in
        /// sim-harness/servo.example.json, missing ones keep the defaults.
        #[arg(long)]
        servo: Option<PathBuf>,
        /// Check the setpoints against the table's curve and limits with the independent checker
        /// (as `feedsim check`); exit 5 if a limit is exceeded.
        #[arg(long)]
        check: bool,
        /// With --check: a ratio fails above 1 + TOL.
        #[arg(long, default_value_t = 0.005, requires = "check")]
        tol: f64,
        /// With --check: ticks at rest added before the first and after the last setpoint.
        #[arg(long, default_value_t = 50, requires = "check")]
        pad_rest: usize,
        /// With --check on a program file: the G-code program it was planned from; every
        /// setpoint is measured against the programmed lines, arcs and NURBS blocks (within 1 um,
        /// or within G64 P where the program allows rounding); exit 5 if one is farther.
        #[arg(long, requires = "check")]
        program: Option<PathBuf>,
    },
    /// Check setpoints against a curve and every limit, with the machine at rest before and after.
    ///
    /// The CSV has a header naming t,x,y,z (further columns are ignored) and one row per servo
    /// tick at a fixed period. Checked: per-axis and path velocity, acceleration and jerk by
    /// central finite differences (with --pad-rest ticks at rest added before and after, so an
    /// acceleration step at the start or stop shows up as jerk), the contour error (distance to
    /// the curve), the start and end points (1e-6 mm) and monotone progress. The curve is
    /// evaluated by the checker's own NURBS code, independent of the planner's and the
    /// firmware's.
    #[command(after_help = EXIT_CODES)]
    Check {
        /// The setpoints (e.g. from `feedsim run --csv`).
        csv: PathBuf,
        /// The toolpath: a JSON file, or a built-in curve: butterfly, circle, fan, star, trident.
        #[arg(long)]
        curve: String,
        /// Limits file (JSON: vbar, abar, jbar, v, a, j); default the paper's Table 1.
        #[arg(long)]
        limits: Option<PathBuf>,
        /// Machine file (machine.toml) whose limits to check against (instead of --limits).
        #[arg(long, conflicts_with = "limits")]
        machine: Option<PathBuf>,
        /// Ticks at rest added before the first and after the last setpoint: a start or stop with
        /// an acceleration step then shows up as a jerk violation.
        #[arg(long, default_value_t = 50)]
        pad_rest: usize,
        /// A ratio fails above 1 + TOL.
        #[arg(long, default_value_t = 0.005)]
        tol: f64,
        /// Largest allowed distance of a setpoint from the curve, mm.
        #[arg(long, default_value_t = 1e-3)]
        contour_tol: f64,
        /// Print one JSON object instead of the text summary.
        #[arg(long)]
        json: bool,
    },
    /// Plan the built-in Butterfly (Table 1 limits, LEN sampling, 1 point/mm), simulate it at 250 us,
    /// write DIR/butterfly.bin, DIR/butterfly.csv and DIR/butterfly_feed.png.
    #[command(after_help = EXIT_CODES)]
    Demo {
        /// Output directory (created if missing).
        #[arg(long, default_value = "out")]
        out: PathBuf,
    },
    /// The sampling study: plan every curve at every density with PAR, LEN and ADA, simulate each,
    /// and write DIR/README.md (Markdown tables) and PNG figures.
    #[command(after_help = EXIT_CODES)]
    Report {
        /// Curves: JSON files or built-in names (default: the five built-in curves).
        curves: Vec<String>,
        /// Sampling densities, points per mm, comma-separated.
        #[arg(long, value_delimiter = ',', default_value = "0.25,0.5,1,2")]
        densities: Vec<f64>,
        /// Output directory.
        #[arg(long, default_value = "docs/sampling")]
        out: PathBuf,
        /// Formulations, comma-separated: paper (q-hat bound none, uniform weights), default
        /// (control, integral) or BOUND/OBJECTIVE; the first is the solid line of the figures.
        #[arg(long, value_delimiter = ',', default_value = "paper,default")]
        formulations: Vec<sim_harness::report::sampling::Formulation>,
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
    /// Feedrate override and feed hold scenarios: the paper's Figs 13-15, an override storm, feed
    /// holds and link faults, each planned with its override levels and simulated with a
    /// host-firmware link model; writes DIR/README.md, a CSV and a feed plot per scenario.
    #[command(after_help = EXIT_CODES)]
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
        /// The Fig. 15 curve: a JSON file or a built-in name (default: the built-in Trident).
        #[arg(long)]
        trident: Option<String>,
        /// Servo period, microseconds.
        #[arg(long, default_value_t = 250.0)]
        period_us: f64,
    },
    /// Stream a plan to the firmware over a simulated serial link: plan the curve in windows
    /// while the machine runs (or whole first, with --whole), cut the plan into checked chunks,
    /// find each chunk's hold point (where the firmware, lacking the next chunk, presses a feed
    /// hold that still stops inside the chunks it holds) by the firmware's own dry run, send the
    /// chunks framed over a link of that rate and latency with credits from the firmware's
    /// ring, and run the firmware's streamed tick on them; check the setpoints against every
    /// limit (50 ticks at rest before and after). Exit 5 if a limit is exceeded.
    #[command(after_help = EXIT_CODES)]
    Stream {
        /// The toolpath: a JSON file, a built-in curve (butterfly, circle, fan, star, trident), or a
        /// part program (.ngc, .nc, .tap, or any file that does not start with '{'): its paths
        /// planned with the machine's limits and each path's feed, and streamed one after
        /// another, each from rest where the one before it stopped.
        curve: String,
        /// Machine file (machine.toml): its limits, rapid velocity and servo period; default
        /// the built-in Table 1 machine.
        #[arg(long)]
        machine: Option<PathBuf>,
        /// The link: uart:BAUD (8N1, BAUD/10 bytes/s).
        #[arg(long, default_value = "uart:2000000")]
        link: String,
        /// One-way link latency, milliseconds.
        #[arg(long, default_value_t = 5.0)]
        latency_ms: f64,
        /// The firmware's chunk ring, bytes (a power of two, 4096 ..= 1048576).
        #[arg(long, default_value_t = 16384)]
        ring_bytes: usize,
        /// Chunk length, mm (a chunk longer than a quarter of the ring is halved).
        #[arg(long, default_value_t = 32.0)]
        chunk_mm: f64,
        /// The firmware's plan window, Q:P (q spans, pieces): 64:128 (the QEMU build's,
        /// about 40 KB of rows), 128:256, 256:512 or 2048:4096 (a host's). The hold points
        /// are found for it
        #[arg(long, default_value = "2048:4096")]
        window_rows: String,
        /// How the host plans: windows, sampling (boxed: the variant's size).
        #[command(flatten)]
        plan: Box<StreamPlanArgs>,
        /// Plan the whole path before the first motion, as `feedplan plan` does, instead of in
        /// windows while the machine runs.
        #[arg(long, conflicts_with_all = ["window_mm", "first_window", "host_slowdown", "ready_times"])]
        whole: bool,
        /// The first window shorter, WINDOW_MM:COMMIT_MM: the machine waits for it alone.
        /// Its commit must reach past where a feed hold pressed while accelerating from
        /// rest comes to rest (and a chunk beyond), or the first motion waits for the
        /// second window too.
        #[arg(long)]
        first_window: Option<planner_host::plan::FirstWindow>,
        /// The host sends no chunk until the hold points it has found reach this far along
        /// the path, mm (or the plan is complete): a later first motion, but no stop for
        /// want of chunks while the planning has not yet got ahead of the machine.
        #[arg(long, default_value_t = 0.0)]
        start_runway_mm: f64,
        /// Hold points searched for chunks at least this far apart, mm (their ends); the
        /// chunks between (at most three, an eighth of the ring and a quarter of the plan
        /// window's rows) have none of their own and the firmware takes them together with
        /// the next that has. The search ticks a whole stop for each of its tests, about a
        /// dozen a chunk whatever its length: wider spacing, less host CPU, and a stop for
        /// want of chunks up to that much earlier. The default, four chunks of 32 mm, is
        /// the most a feed change's splice allows at that size. 0: every chunk its own
        #[arg(long, default_value_t = 128.0)]
        hold_every_mm: f64,
        /// A link stall: START:DURATION in seconds from the start of sending (repeatable).
        #[arg(long)]
        stall: Vec<String>,
        /// The operator's feed hold: pressed at TIME seconds from the start of sending (at
        /// the first tick after it that the machine moves), cycle start pressed once it has
        /// rested HELD seconds (repeatable). The report lists where each stop came to rest
        /// and the end of the rows held then.
        #[arg(long)]
        hold: Vec<String>,
        /// A feedrate override while streaming: at T seconds from the start of sending,
        /// PCT percent of the programmed feed (repeatable, in time order). The host replans
        /// the path ahead at the new feed and the firmware splices it in; the check holds
        /// the feed to each override once it applies. In a part program it holds from T
        /// on, path after path: a feed path that starts later is planned at it (rapids
        /// keep the rapid rate).
        #[arg(long = "override")]
        overrides: Vec<String>,
        /// With --override: each replan's chunks ready this many milliseconds after its
        /// ask, whatever it took on this machine (runs that do not depend on its speed).
        #[arg(long)]
        host_replan_ms: Option<f64>,
        /// Planning in windows: a host this many times slower, each chunk ready this many
        /// times later than it was here (a slower computer beside the machine).
        #[arg(long, default_value_t = 1.0)]
        host_slowdown: f64,
        /// Planning in windows: write each chunk's ready time (s, one a line) to FILE, or,
        /// if FILE exists, read them from it (a run replayed with the same timing).
        #[arg(long)]
        ready_times: Option<PathBuf>,
        /// Damage on the link: KIND:N,... with KIND corrupt, drop, duplicate or reorder
        /// (every Nth DATA frame sent, resends counted: a bit flipped, lost, sent twice,
        /// after the next one) and restart:SECONDS (the host restarts then, sending from
        /// the first chunk again). The firmware refuses and NAKs, the host resends; the
        /// report's "link" counts what was sent and refused. In a part program the times
        /// are from its start and the frames are counted in each path's session.
        #[arg(long)]
        faults: Option<String>,
        /// A part program: at each program stop (M0, M1) and tool change (M6) the operator
        /// presses cycle start this many milliseconds after the machine comes to rest, and
        /// the next path streams then (default: the program goes on at once).
        #[arg(long)]
        cycle_start_ms: Option<f64>,
        /// Chunks with the u form (each piece's u(s), six f32: 70 % more bytes on the
        /// Butterfly) so that the setpoints report u, the curve parameter; without it
        /// (the default) their u reads 0 along the path (the end point's at the end) and
        /// the positions, s, the feed and the time are the same bits.
        #[arg(long)]
        u_form: bool,
        /// Servo period, microseconds (default: the machine file's; the built-in machine's is 250).
        #[arg(long)]
        period_us: Option<f64>,
        /// A ratio fails above 1 + TOL.
        #[arg(long, default_value_t = 0.01)]
        tol: f64,
        /// Print one JSON object instead of the text summary (a part program's: its figures
        /// and a row per path, kept in a temporary file as the paths end and printed when the
        /// program has run: nothing is printed if it fails).
        #[arg(long)]
        json: bool,
    },
    /// Print a shell completion script (bash, zsh, fish, elvish, powershell) to stdout.
    #[command(after_help = EXIT_CODES)]
    Completions {
        /// The shell.
        shell: clap_complete::Shell,
    },
}

/// How `feedsim stream` plans the path: its windows and sampling.
#[derive(clap::Args)]
struct StreamPlanArgs {
    /// Plan in windows of this much path (mm), with --commit-mm, while the machine runs
    /// [default: 400 mm committing 350 (a part program's paths 200 committing 150), a path no longer than 400 mm planned whole; with
    /// --window-mm, one no longer than a window].
    #[arg(long, requires = "commit_mm")]
    window_mm: Option<f64>,
    /// Path each window commits, mm.
    #[arg(long, requires = "window_mm")]
    commit_mm: Option<f64>,
    /// Sampling of the toolpath: par, len or ada (paper §3); a part program is sampled len.
    #[arg(long, default_value = "len")]
    sampling: Sampling,
    /// Sampling density, points per mm of arc length: fewer plan faster, for a little
    /// machining time (docs/streaming-design.md, "Sampling density").
    #[arg(long, default_value_t = 1.0)]
    density: f64,
    /// Sampling density where the plan can cruise at the feed limit, points per mm (a curve
    /// sampled len): elsewhere --density. The samples are kept only every DENSITY/CRUISE-th
    /// where no bend, curvature jump or end within a stop's distance needs a lower feed: the
    /// same plan where it matters, fewer LP columns where it cruises; equal to --density to
    /// keep every sample (docs/streaming-design.md, "Sampling density")
    #[arg(long, default_value_t = 0.125)]
    cruise_density: f64,
}

type BoxError = Box<dyn std::error::Error>;

/// An error with its exit code (see [`EXIT_CODES`]).
struct Failure {
    code: u8,
    message: String,
}

impl Failure {
    /// An error with this exit code.
    fn new(code: u8, e: impl Display) -> Failure {
        Failure {
            code,
            message: e.to_string(),
        }
    }
    /// 3: the input is unreadable or invalid.
    fn input(e: impl Display) -> Failure {
        Failure {
            code: EXIT_INPUT,
            message: e.to_string(),
        }
    }
    /// 2: an option's value is unusable, or the option does not fit.
    fn usage(e: impl Display) -> Failure {
        Failure {
            code: planner_host::cli::EXIT_USAGE,
            message: e.to_string(),
        }
    }
    /// 5: a limit is exceeded.
    fn limit(e: impl Display) -> Failure {
        Failure {
            code: EXIT_LIMIT,
            message: e.to_string(),
        }
    }
}

/// Everything else is an I/O or internal error (1).
impl<E: Into<BoxError>> From<E> for Failure {
    fn from(e: E) -> Failure {
        Failure {
            code: EXIT_IO,
            message: e.into().to_string(),
        }
    }
}

/// A planner error with the exit code both tools give it
/// ([`planner_host::cli::plan_exit_code`]).
fn plan_failure(e: PlanError) -> Failure {
    Failure {
        code: planner_host::cli::plan_exit_code(&e),
        message: e.to_string(),
    }
}

/// A simulation error's exit code: a table, servo model or period the
/// interpolator or the servos cannot use is bad input (3), else 1.
fn sim_failure(e: SimError, table: &Path) -> Failure {
    let message = format!("{}: {e}", table.display());
    match e {
        SimError::Table(_) | SimError::Interp(_) | SimError::Servo(_) | SimError::Unstable { .. } => {
            Failure::input(message)
        }
        _ => message.into(),
    }
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("feedsim: error: {}", e.message);
            ExitCode::from(e.code)
        }
    }
}

/// The exit code and message of a failed stream (see [`EXIT_CODES`]).
fn stream_failure(e: sim_harness::stream::StreamError) -> Failure {
    use sim_harness::stream::StreamError as E;
    match e {
        E::Plan(p) | E::Pipeline(planner_host::stream_pipeline::PipelineError::Plan(p)) => plan_failure(p),
        e @ (E::RingBytes(_) | E::WindowRows(..) | E::Option(_)) => Failure::usage(e),
        e @ E::ReadyTimes(_) => Failure::input(e),
        // (an option that does not fit the plan)
        e @ E::Run(
            sim_harness::stream::StreamRunError::WindowTooSmall { .. }
            | sim_harness::stream::StreamRunError::WindowStuck { .. },
        ) => Failure {
            code: planner_host::cli::EXIT_USAGE,
            message: e.to_string(),
        },
        // (the window too small for the chunks: the options, not the plan)
        E::HoldPoints(e @ planner_host::stream_hold::HoldPointError::RowsRunOut { .. })
        | E::Pipeline(planner_host::stream_pipeline::PipelineError::HoldPoints(
            e @ planner_host::stream_hold::HoldPointError::RowsRunOut { .. },
        )) => Failure {
            code: planner_host::cli::EXIT_USAGE,
            message: format!("{e} (a larger --window-rows or a shorter --chunk-mm)"),
        },
        E::Program(p) => Failure::new(planner_host::cli::program_exit_code(&p), p),
        E::Path {
            index,
            first_line,
            last_line,
            source,
        } => {
            let inner = stream_failure(*source);
            Failure::new(
                inner.code,
                format!("LINE {first_line}..{last_line}: path {index}: {}", inner.message),
            )
        }
        e => Failure::from(e.to_string()),
    }
}

/// A stream's ring and window line: (capacity, peak) of each, the longest
/// hold lead and the chunks without a hold point of their own, (starvation
/// holds, ticks starved).
fn ring_text(
    ring: (usize, usize),
    window: (usize, usize),
    (lead_mm, alone_not): (f64, usize),
    starved: (u64, u64),
) -> String {
    let without = match alone_not {
        0 => String::new(),
        1 => " (1 chunk without a hold point of its own)".to_string(),
        n => format!(" ({n} chunks without a hold point of their own)"),
    };
    format!(
        "  ring {} B (peak {} B), window {} pieces (peak {}), longest hold lead {lead_mm:.1} mm{without}; {} starvation holds, {} ticks starved",
        ring.0, ring.1, window.0, window.1, starved.0, starved.1
    )
}

/// A stream's ratios line.
fn ratios_text(label: &str, r: &planner_host::Ratios, ok: bool) -> String {
    format!(
        "  {label}: vel {:.4} acc {:.4} jerk {:.4} feed {:.4} tacc {:.4} tjerk {:.4}: {}",
        r.vel,
        r.acc,
        r.jerk,
        r.feed,
        r.tacc,
        r.tjerk,
        if ok { "ok" } else { "over the limits" }
    )
}

/// "; peak RSS … MiB" where the system tells it.
fn rss_text(kib: Option<u64>) -> String {
    kib.map_or(String::new(), |k| {
        format!("; peak RSS {:.1} MiB", k as f64 / 1024.0)
    })
}

/// What the summary line says of a stream sent with the u form.
fn u_form_note(u_form: bool) -> &'static str {
    if u_form {
        " (with the u form)"
    } else {
        ""
    }
}

/// Paths of a program listed by name in the text report at most: a long
/// program's (its paths planned at an override, those over a limit) are
/// counted beyond these, not held.
const PATHS_LISTED: usize = 20;

/// `feedsim stream PART.ngc`: every path streamed in turn. A path's row
/// leaves memory as the path ends: with `--json` into an unnamed spool file
/// (the report is written whole at the end, nothing if the program fails),
/// in the text report as the few it names.
fn stream_program_cmd(
    path: &Path,
    machine: &planner_host::Machine,
    opts: &sim_harness::stream::StreamOptions,
    density_per_mm: f64,
    json: bool,
) -> Result<(), Failure> {
    use planner_host::gcode;
    use sim_harness::stream::StreamError;
    use std::io::{BufWriter, Seek as _, Write as _};
    let bytes =
        std::fs::read(path).map_err(|e| Failure::input(format!("cannot read {}: {e}", path.display())))?;
    // (read as it streams: the program's moves are never all held)
    let text = gcode::lex::text_of(&bytes).map_err(|e| Failure::input(format!("{}: {e}", path.display())))?;
    let source =
        sim_harness::stream_program::ProgramSource::Text(text, gcode::ReadOptions { block_delete: false });
    let popts = planner_host::program::ProgramOptions {
        density_per_mm,
        ..planner_host::program::ProgramOptions::default()
    };
    let mut spool = match json {
        true => Some(BufWriter::new(
            tempfile::tempfile().map_err(|e| format!("a spool file for the path rows: {e}"))?,
        )),
        false => None,
    };
    let (mut planned, mut planned_more) = (Vec::new(), 0usize);
    let (mut over, mut over_more) = (Vec::new(), 0usize);
    let mut rows = 0usize;
    let rep = sim_harness::stream_program::stream_program_rows(source, machine, &popts, opts, &mut |p| {
        if let Some(w) = spool.as_mut() {
            if rows > 0 {
                w.write_all(b",").map_err(StreamError::Rows)?;
            }
            serde_json::to_writer(&mut *w, &p).map_err(|e| StreamError::Rows(e.into()))?;
        } else {
            if p.feed_factor != 1.0 {
                match planned.len() < PATHS_LISTED {
                    true => planned.push(format!("{} at {:.0} %", p.index, p.feed_factor * 100.0)),
                    false => planned_more += 1,
                }
            }
            if !p.check_ok {
                match over.len() < PATHS_LISTED {
                    true => over.push(p),
                    false => over_more += 1,
                }
            }
        }
        rows += 1;
        Ok(())
    })
    .map_err(|e| {
        let f = stream_failure(e);
        Failure::new(f.code, format!("{}: {}", path.display(), f.message))
    })?;
    if let Some(w) = spool {
        // the report with its rows in place: `"path":[]` is its last field
        let mut file = w
            .into_inner()
            .map_err(|e| format!("the path rows: {}", e.error()))?;
        let head = serde_json::to_string(&rep)?;
        let Some(head) = head.strip_suffix("[]}") else {
            return Err(Failure::from("the stream report does not end with its paths"));
        };
        file.rewind()?;
        let mut stdout = std::io::stdout().lock();
        let written = stdout
            .write_all(head.as_bytes())
            .and_then(|_| stdout.write_all(b"["))
            .and_then(|_| std::io::copy(&mut file, &mut stdout).map(drop))
            .and_then(|_| stdout.write_all(b"]}\n"))
            .and_then(|_| stdout.flush());
        if let Err(e) = written {
            planner_host::cli::stdout_failed(env!("CARGO_BIN_NAME"), e);
        }
    } else {
        outln!(
            "{}: {} paths, {:.2} mm streamed in {} chunks, {:.1} bytes/mm framed{}, over uart:{} with {} ms latency",
            path.display(), rep.paths, rep.length_mm, rep.chunks, rep.bytes_per_mm,
            u_form_note(rep.u_form), rep.link_baud, rep.latency_ms
        );
        outln!(
            "  planning {:.3} s ({} windows), first motion after {:.1} ms, at rest between paths {:.1} ms in all; machining {:.3} s ({:.0}x the planning time, {:.0}x the host's with the hold points), the plans' own {:.3} s{}",
            rep.plan_s, rep.windows, rep.first_motion_ms, rep.waits_ms, rep.machining_time_s, rep.plan_realtime_factor, rep.host_realtime_factor, rep.planned_time_s, rss_text(rep.peak_rss_kib)
        );
        outln!(
            "{}",
            ring_text(
                (rep.ring_bytes, rep.ring_peak_bytes),
                (rep.window_pieces, rep.window_peak_pieces),
                (rep.hold_lead_max_mm, rep.chunks_without_hold_point),
                (rep.starvations, rep.starved_ticks)
            )
        );
        outln!(
            "{}",
            ratios_text(
                "ratios (each path against its own limits)",
                &rep.ratios,
                rep.check_ok
            )
        );
        if rep.program_stops > 0 {
            outln!(
                "  {} program stop(s) and tool change(s) between paths, the operator's cycle start awaited {:.3} s in all",
                rep.program_stops, rep.operator_wait_s
            );
        }
        if rep.overrides > 0 || !planned.is_empty() {
            if planned_more > 0 {
                planned.push(format!("and {planned_more} more"));
            }
            outln!(
                "  feed override: {} change(s) made while a path ran, paths planned at an override: {}; feed against each override once it holds: {:.4}",
                rep.overrides,
                if planned.is_empty() { "none".to_string() } else { planned.join(", ") },
                rep.override_feed_ratio
            );
        }
        for p in &over {
            outln!(
                "  path {} (LINE {}..{}) over its limits: {:?}",
                p.index,
                p.first_line,
                p.last_line,
                p.ratios
            );
        }
        if over_more > 0 {
            outln!("  and {over_more} more paths over their limits");
        }
    }
    if rep.check_ok {
        Ok(())
    } else {
        Err(Failure::limit(
            "a streamed setpoint exceeds a limit (see the ratios)",
        ))
    }
}

/// A curve argument: an existing JSON file, else the name of a built-in
/// curve ([`planner_host::cli::load_curve`]).
fn load_curve(arg: &str) -> Result<Nurbs, Failure> {
    planner_host::cli::load_curve(Path::new(arg)).map_err(Failure::input)
}

/// Curve arguments of `feedsim report` as files (the report reads files): an
/// existing file as is, a built-in name written to a temporary directory that
/// the returned guard removes. No arguments: the five built-in curves.
fn report_curve_files(args: &[String]) -> Result<(Vec<PathBuf>, tempfile::TempDir), Failure> {
    let names: Vec<String> = if args.is_empty() {
        planner_host::builtin::NAMES
            .iter()
            .map(|n| n.to_string())
            .collect()
    } else {
        args.to_vec()
    };
    let tmp = tempfile::Builder::new()
        .prefix("feedsim-curves-")
        .tempdir()
        .map_err(|e| format!("cannot create a temporary directory: {e}"))?;
    let mut files = Vec::new();
    for arg in &names {
        let path = Path::new(arg);
        if path.exists() {
            files.push(path.to_path_buf());
            continue;
        }
        let Some(json) = planner_host::builtin::json(arg) else {
            return Err(Failure::input(planner_host::cli::CurveArgError::Unknown(
                arg.clone(),
            )));
        };
        let file = tmp.path().join(format!("{}.json", arg.to_ascii_lowercase()));
        std::fs::write(&file, json).map_err(|e| format!("cannot write {}: {e}", file.display()))?;
        files.push(file);
    }
    Ok((files, tmp))
}

fn check_period(period_us: f64) -> Result<(), Failure> {
    if period_us.is_finite() && period_us > 0.0 {
        Ok(())
    } else {
        Err(Failure::usage(format!(
            "--period-us must be a positive number, got {period_us}"
        )))
    }
}

/// `feedsim check --json`: the report (`schema_version` first) and its inputs.
#[derive(serde::Serialize)]
struct CheckOut<'a> {
    #[serde(flatten)]
    report: &'a CheckReport,
    csv: String,
    curve: String,
}

/// `feedsim run --json`: the run's summary and the files written.
#[derive(serde::Serialize)]
struct RunOut<'a> {
    schema_version: u32,
    #[serde(flatten)]
    summary: sim_harness::run::SimSummary<'a>,
    table: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    csv: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    plot: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    check: Option<&'a CheckReport>,
    #[serde(skip_serializing_if = "Option::is_none")]
    steps: Option<sim_harness::steps::StepReport>,
}

/// The machine's step output over `ticks` (when the machine file has a
/// `[stepgen]`); exit 5 when a period needs more steps than the drives take.
fn step_output(
    ticks: &[sim_harness::Tick],
    machine: &planner_host::Machine,
    period_s: f64,
    what: &Path,
) -> Result<Option<sim_harness::steps::StepReport>, Failure> {
    let Some(cfg) = &machine.step_output else {
        return Ok(None);
    };
    let period_ns = (period_s * 1e9).round() as u32;
    sim_harness::steps::step_report(ticks, cfg, period_ns)
        .map(Some)
        .map_err(|e| Failure::limit(format!("{}: step output: {e}", what.display())))
}

fn step_text(r: &sim_harness::steps::StepReport) -> String {
    format!(
        "step output: {} / {} / {} steps (x / y / z), at most {} / {} / {} in a {} ns period (the drives take {})",
        r.steps[0],
        r.steps[1],
        r.steps[2],
        r.peak_per_period[0],
        r.peak_per_period[1],
        r.peak_per_period[2],
        r.period_ns,
        r.max_per_period
    )
}

/// Exit 5 naming what failed when the check did not pass.
fn check_verdict(rep: &CheckReport) -> Result<(), Failure> {
    if rep.ok {
        return Ok(());
    }
    let what: Vec<String> = rep
        .fail
        .iter()
        .map(
            |f| match (f.as_str(), rep.ratios.named().iter().find(|(n, _)| n == f)) {
                (_, Some((n, p))) => {
                    format!("{n} ratio {:.4} > 1 + {} at t = {:.4} s", p.ratio, rep.tol, p.t_s)
                }
                ("contour", _) => format!(
                    "contour error {:.3e} mm > {} mm at t = {:.4} s",
                    rep.contour.max_mm, rep.contour.tol_mm, rep.contour.t_s
                ),
                ("endpoints", _) => format!(
                    "start and end {:.3e} mm and {:.3e} mm from the curve's ends (> {} mm)",
                    rep.start_err_mm,
                    rep.end_err_mm,
                    check::ENDPOINT_TOL_MM
                ),
                ("monotone", _) => format!("progress goes backwards by {:.3e} mm", -rep.min_ds_mm),
                (other, _) => other.to_string(),
            },
        )
        .collect();
    Err(Failure::limit(format!("the check failed: {}", what.join("; "))))
}

fn run(cli: Cli) -> Result<(), Failure> {
    match cli.cmd {
        Cmd::Run {
            table,
            period_us,
            machine,
            csv,
            plot,
            json,
            servo,
            check,
            tol,
            pad_rest,
            program,
        } => {
            let bytes = std::fs::read(&table).map_err(|e| format!("cannot read {}: {e}", table.display()))?;
            let is_program = planner_host::program::ProgramFile::is_program(&bytes);
            // a program file without --period-us or --machine runs at the period its tables
            // were planned for
            let program_period_us = match (is_program, period_us, &machine) {
                (true, None, None) => planner_host::program::ProgramFile::parse(&bytes)
                    .map(|f| f64::from(f.servo_period_ns) * 1e-3)
                    .ok(),
                _ => None,
            };
            let machine =
                planner_host::cli::load_machine(machine.as_deref(), None).map_err(Failure::input)?;
            let period_us = period_us
                .or(program_period_us)
                .unwrap_or(machine.servo_period_s * 1e6);
            check_period(period_us)?;
            let mut cfg = SimConfig {
                period_s: period_us * 1e-6,
                ..SimConfig::default()
            };
            if let Some(path) = servo {
                cfg.servo = ServoConfig::load_axes(&path).map_err(Failure::input)?;
            }
            if is_program {
                let opts = ProgramRunOptions {
                    csv: csv.as_deref(),
                    plot: plot.as_deref(),
                    json,
                    check: check.then_some((tol, pad_rest)),
                    program: program.as_deref(),
                    machine: &machine,
                };
                return run_program_cmd(&table, &bytes, &cfg, &opts);
            }
            if program.is_some() {
                return Err(Failure {
                    code: planner_host::cli::EXIT_USAGE,
                    message: "--program goes with a program file (feedplan plan PART.ngc)".into(),
                });
            }
            let res = run_table(&bytes, &cfg).map_err(|e| sim_failure(e, &table))?;
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
            let report = if check {
                Some(
                    check_run(&bytes, &res, tol, pad_rest)
                        .map_err(|e| format!("{}: {}", table.display(), e.message))?,
                )
            } else {
                None
            };
            let steps = step_output(&res.ticks, &machine, cfg.period_s, &table)?;
            if json {
                let out = RunOut {
                    schema_version: check::SCHEMA_VERSION,
                    summary: res.summary_json(),
                    table: table.display().to_string(),
                    csv: csv.as_ref().map(|p| p.display().to_string()),
                    plot: plot.as_ref().map(|p| p.display().to_string()),
                    check: report.as_ref(),
                    steps,
                };
                outln!("{}", serde_json::to_string(&out)?);
            } else {
                outln!("{}", table.display());
                out!("{}", res.summary());
                if let Some(p) = &csv {
                    outln!("  wrote {}", p.display());
                }
                if let Some(p) = &plot {
                    outln!("  wrote {}", p.display());
                }
                if let Some(r) = &report {
                    outln!("check against the table's curve and limits:");
                    out!("{}", r.text());
                }
                if let Some(r) = &steps {
                    outln!("{}", step_text(r));
                }
            }
            report.as_ref().map_or(Ok(()), check_verdict)
        }
        Cmd::Check {
            csv,
            curve,
            limits: limits_file,
            machine,
            pad_rest,
            tol,
            contour_tol,
            json,
        } => {
            if !(tol.is_finite() && tol >= 0.0 && contour_tol.is_finite() && contour_tol > 0.0) {
                return Err(Failure::usage(format!(
                    "--tol must be >= 0 and --contour-tol > 0, got {tol} and {contour_tol}"
                )));
            }
            let nurbs = load_curve(&curve)?;
            let lim = match (&limits_file, &machine) {
                (Some(p), _) => limits::load(p).map_err(Failure::input)?,
                (None, Some(m)) => planner_host::Machine::load(m).map_err(Failure::input)?.limits,
                (None, None) => limits::TABLE1,
            };
            let traj =
                Trajectory::load(&csv).map_err(|e| Failure::input(format!("{}: {e}", csv.display())))?;
            let cfg = CheckConfig {
                limits: lim,
                pad_rest,
                tol,
                contour_tol,
            };
            let rep = check::check_trajectory(&nurbs, &traj, &cfg)
                .map_err(|e| Failure::input(format!("{}: {e}", csv.display())))?;
            if json {
                let out = CheckOut {
                    report: &rep,
                    csv: csv.display().to_string(),
                    curve,
                };
                outln!("{}", serde_json::to_string(&out)?);
            } else {
                outln!("{} against {} ({}):", csv.display(), curve, nurbs.name);
                out!("{}", rep.text());
            }
            check_verdict(&rep)
        }
        Cmd::Demo { out } => demo(&out),
        Cmd::Stream {
            curve,
            machine,
            link,
            latency_ms,
            ring_bytes,
            chunk_mm,
            window_rows,
            plan,
            whole,
            first_window,
            start_runway_mm,
            hold_every_mm,
            stall,
            hold,
            overrides,
            host_replan_ms,
            host_slowdown,
            ready_times,
            faults,
            cycle_start_ms,
            u_form,
            period_us,
            tol,
            json,
        } => {
            let StreamPlanArgs {
                window_mm,
                commit_mm,
                sampling,
                density,
                cruise_density,
            } = *plan;
            let machine =
                planner_host::cli::load_machine(machine.as_deref(), None).map_err(Failure::input)?;
            let period_us = period_us.unwrap_or(machine.servo_period_s * 1e6);
            check_period(period_us)?;
            if !(density.is_finite() && density > 0.0) {
                return Err(Failure::usage(format!(
                    "--density {density}: must be a number > 0"
                )));
            }
            if !(cruise_density.is_finite() && cruise_density > 0.0) {
                return Err(Failure::usage(format!(
                    "--cruise-density {cruise_density}: must be a number > 0"
                )));
            }
            if !(hold_every_mm.is_finite() && hold_every_mm >= 0.0) {
                return Err(Failure::usage(format!(
                    "--hold-every-mm {hold_every_mm}: must be a number ≥ 0"
                )));
            }
            if !(host_slowdown.is_finite() && host_slowdown > 0.0) {
                return Err(Failure::usage(format!(
                    "--host-slowdown {host_slowdown}: expected a factor > 0"
                )));
            }
            let window_rows = window_rows
                .split_once(':')
                .and_then(|(q, p)| Some((q.parse::<usize>().ok()?, p.parse::<usize>().ok()?)))
                .ok_or_else(|| {
                    Failure::usage(format!("--window-rows {window_rows}: expected Q:P, e.g. 128:256"))
                })?;
            let baud = link
                .strip_prefix("uart:")
                .and_then(|b| b.parse::<f64>().ok())
                .filter(|b| b.is_finite() && *b > 0.0)
                .ok_or_else(|| {
                    Failure::usage(format!("--link {link}: expected uart:BAUD, e.g. uart:115200"))
                })?;
            let intervals = |v: &[String], zero: bool| {
                v.iter()
                    .map(|s| {
                        let (a, d) = s.split_once(':')?;
                        let (a, d) = (a.parse::<f64>().ok()?, d.parse::<f64>().ok()?);
                        (a >= 0.0 && a.is_finite() && d.is_finite() && (d > 0.0 || zero && d == 0.0))
                            .then_some((a, d))
                    })
                    .collect::<Option<Vec<_>>>()
            };
            let stalls = intervals(&stall, false)
                .ok_or_else(|| Failure::usage("--stall: expected START:DURATION in seconds, e.g. 1.0:0.5"))?;
            let holds = intervals(&hold, true)
                .ok_or_else(|| Failure::usage("--hold: expected TIME:HELD in seconds, e.g. 2.0:1.5"))?;
            let overrides = overrides
                .iter()
                .map(|s| {
                    let (t, p) = s.split_once(':')?;
                    let (t, p) = (t.parse::<f64>().ok()?, p.parse::<f64>().ok()?);
                    (t >= 0.0 && p > 0.0 && p.is_finite()).then_some((t, p / 100.0))
                })
                .collect::<Option<Vec<_>>>()
                .filter(|v| v.windows(2).all(|w| w[0].0 <= w[1].0))
                .ok_or_else(|| {
                    Failure::usage(
                        "--override: expected T:PCT (seconds, percent > 0), in time order, e.g. 1.5:50",
                    )
                })?;
            let faults = match &faults {
                None => Default::default(),
                Some(f) => sim_harness::stream::LinkFaults::parse(f).ok_or_else(|| {
                    Failure::usage(format!(
                        "--faults {f}: expected KIND:N,... (corrupt, drop, duplicate, reorder: every N ≥ 1 \
                         frames; restart:SECONDS), e.g. corrupt:17,drop:23,restart:1.5"
                    ))
                })?,
            };
            if host_replan_ms.is_some_and(|h| !(h.is_finite() && h >= 0.0)) {
                return Err(Failure::usage("--host-replan-ms: expected a time ≥ 0"));
            }
            if cycle_start_ms.is_some_and(|c| !(c.is_finite() && c >= 0.0)) {
                return Err(Failure::usage("--cycle-start-ms: expected a time ≥ 0"));
            }
            let opts = sim_harness::stream::StreamOptions {
                overrides,
                holds,
                host_replan_s: host_replan_ms.map(|h| h * 1e-3),
                baud,
                latency_s: latency_ms * 1e-3,
                ring_bytes,
                chunk_mm,
                windows: (!whole).then(|| {
                    let asked = window_mm
                        .zip(commit_mm)
                        .map(|(w, c)| planner_host::plan::WindowConfig::new(w, c));
                    let default = match planner_host::cli::is_gcode_program(Path::new(&curve)) {
                        true => sim_harness::stream::PROGRAM_WINDOWS,
                        false => sim_harness::stream::WINDOWS,
                    };
                    planner_host::plan::WindowConfig {
                        first: first_window,
                        ..asked.unwrap_or(default)
                    }
                }),
                stalls,
                window_rows,
                period_s: period_us * 1e-6,
                tol,
                host_slowdown,
                ready_times,
                host_ahead_s: 0.0,
                start_runway_mm,
                hold_every_mm,
                u_form,
                faults,
                cycle_start_s: cycle_start_ms.map(|m| m * 1e-3),
            };
            if planner_host::cli::is_gcode_program(Path::new(&curve)) {
                if sampling != Sampling::Len {
                    return Err(Failure::usage(
                        "--sampling goes with a curve: a part program's paths are sampled len",
                    ));
                }
                return stream_program_cmd(Path::new(&curve), &machine, &opts, density, json);
            }
            let nurbs = load_curve(&curve)?;
            let base = planner_host::plan::PlanConfig {
                limits: machine.limits,
                sampling,
                density_per_mm: density,
                cruise_density_per_mm: Some(cruise_density),
                ..planner_host::plan::PlanConfig::default()
            };
            let rep = sim_harness::stream::stream_curve_with(&nurbs, &base, &opts).map_err(stream_failure)?;
            if json {
                outln!("{}", serde_json::to_string(&rep)?);
            } else {
                outln!(
                    "{}: {:.2} mm streamed in {} chunks, {:.1} bytes/mm framed{}, over uart:{} with {} ms latency",
                    curve, rep.length_mm, rep.chunks, rep.bytes_per_mm,
                    u_form_note(rep.u_form), rep.link_baud, rep.latency_ms
                );
                outln!(
                    "  planning {:.3} s ({} windows), hold points {:.3} s, first motion after {:.1} ms; machining {:.3} s ({:.0}x the planning time, {:.0}x the host's with the hold points), the plan's own {:.3} s{}",
                    rep.plan_s, rep.windows, rep.hold_points_s, rep.first_motion_ms, rep.machining_time_s, rep.plan_realtime_factor, rep.host_realtime_factor, rep.planned_time_s, rss_text(rep.peak_rss_kib)
                );
                outln!(
                    "{}{}",
                    ring_text(
                        (rep.ring_bytes, rep.ring_peak_bytes),
                        (rep.window_pieces, rep.window_peak_pieces),
                        (rep.hold_lead_max_mm, rep.chunks_without_hold_point),
                        (rep.starvations, rep.starved_ticks)
                    ),
                    rep.starved_room_min_mm.map_or(String::new(), |r| format!(
                        ", each stop at least {r:.2} mm short of its rows' end"
                    ))
                );
                outln!("{}", ratios_text("ratios", &rep.ratios, rep.check_ok));
                for o in &rep.overrides {
                    let at = |t: Option<f64>| t.map_or("never".to_string(), |t| format!("{t:.3} s"));
                    outln!(
                        "  override {:.0} % asked at {:.3} s (motion known at {:.2} mm): splice at {:.2} mm, new feed from {:.2} mm; host {:.0} ms, taken {}, on the replan {} ({}), at the new feed {}; {} late",
                        o.alpha * 100.0,
                        o.asked_s,
                        o.known_mm,
                        o.splice_mm,
                        o.feed_from_mm,
                        o.host_s * 1e3,
                        at(o.taken_s),
                        at(o.effect_s),
                        o.effect_s.map_or("-".to_string(), |e| format!("{:.0} ms after the ask", (e - o.asked_s) * 1e3)),
                        at(o.at_feed_s),
                        o.late
                    );
                }
                if !rep.overrides.is_empty() {
                    outln!(
                        "  feed against each override once it holds: {:.4}",
                        rep.override_feed_ratio
                    );
                }
                for h in &rep.operator_holds {
                    outln!(
                        "  feed hold pressed at {:.2} mm: at rest at {:.2} mm, rows held to {:.2} mm",
                        h[0],
                        h[1],
                        h[2]
                    );
                }
            }
            if rep.check_ok {
                Ok(())
            } else {
                Err(Failure::limit(
                    "a streamed setpoint exceeds a limit (see the ratios)",
                ))
            }
        }
        Cmd::Override {
            scenarios,
            out,
            latency_ms,
            compute_ms,
            trident,
            period_us,
        } => {
            check_period(period_us)?;
            override_report(
                &scenarios,
                &out,
                latency_ms,
                compute_ms,
                trident.as_deref(),
                period_us,
            )
        }
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
            use sim_harness::report::sampling::{run_report, Formulation, ReportConfig};
            check_period(period_us)?;
            let (curves, _tmp) = report_curve_files(&curves)?;
            let formulations = if qhat_bound.is_empty() {
                if objective.is_some() {
                    return Err(Failure::usage(
                        "--objective goes with --qhat-bound (or use --formulations BOUND/OBJECTIVE)",
                    ));
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
                Some(p) => limits::load(p).map_err(Failure::input)?,
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
            let rep = run_report(&cfg)?;
            let failed = rep.rows.iter().filter(|r| r.outcome.is_err()).count();
            outln!(
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
            if rep.curves.is_empty() && !rep.curve_errors.is_empty() {
                return Err(Failure::input("no curve could be loaded"));
            }
            Ok(())
        }
        Cmd::Completions { shell } => {
            clap_complete::generate(shell, &mut Cli::command(), "feedsim", &mut std::io::stdout());
            Ok(())
        }
    }
}

/// `run --check`: the run's setpoints against the table's own curve and limits.
/// What `feedsim run` does with a program file besides running it.
struct ProgramRunOptions<'a> {
    csv: Option<&'a Path>,
    plot: Option<&'a Path>,
    json: bool,
    /// --check: (tol, pad_rest).
    check: Option<(f64, usize)>,
    /// --program: the G-code it was planned from.
    program: Option<&'a Path>,
    /// The machine (its step output, if any).
    machine: &'a planner_host::Machine,
}

/// `feedsim run --json` for a program file.
#[derive(serde::Serialize)]
struct ProgramRunOut<'a> {
    schema_version: u32,
    program: String,
    period_s: f64,
    paths: &'a [sim_harness::program::PathRun],
    stops: &'a [u32],
    blocks_executed: usize,
    last_block: Option<u32>,
    machining_time_s: f64,
    predicted_time_s: f64,
    setpoints: usize,
    warnings: &'a [String],
    #[serde(skip_serializing_if = "Option::is_none")]
    check: Option<&'a [CheckReport]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    programmed_contour: Option<sim_harness::programmed::ProgrammedContour>,
    #[serde(skip_serializing_if = "Option::is_none")]
    steps: Option<sim_harness::steps::StepReport>,
    #[serde(skip_serializing_if = "Option::is_none")]
    csv: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    plot: Option<String>,
}

/// `feedsim run PART.bin` for a program file.
fn run_program_cmd(
    table: &Path,
    bytes: &[u8],
    cfg: &SimConfig,
    o: &ProgramRunOptions,
) -> Result<(), Failure> {
    use sim_harness::program::{check_program, run_program, ProgramRunError};
    let fail = |e: ProgramRunError| {
        let message = format!("{}: {e}", table.display());
        match e {
            ProgramRunError::Sim { source, .. } => sim_failure(source, table),
            ProgramRunError::Gap { .. } | ProgramRunError::File(_) | ProgramRunError::Check { .. } => {
                Failure::input(message)
            }
            _ => message.into(),
        }
    };
    let run = run_program(bytes, cfg).map_err(fail)?;
    if let Some(path) = o.csv {
        run.write_csv(path)?;
    }
    if let Some(path) = o.plot {
        sim_harness::plot::plot_program(path, &run, &table.display().to_string())?;
    }
    let reports = match o.check {
        Some((tol, pad_rest)) => Some(
            check_program(
                &run,
                &CheckConfig {
                    pad_rest,
                    tol,
                    ..CheckConfig::default()
                },
            )
            .map_err(fail)?,
        ),
        None => None,
    };
    let programmed = match o.program {
        Some(path) => {
            let text = std::fs::read(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
            let prog = planner_host::gcode::read_bytes(&text, planner_host::gcode::ReadOptions::default())
                .map_err(|e| Failure::input(format!("{}: {e}", path.display())))?;
            Some(
                sim_harness::programmed::programmed_contour(&run, &prog)
                    .map_err(|e| Failure::input(format!("{}: {e}", path.display())))?,
            )
        }
        None => None,
    };
    let predicted: f64 = run.paths.iter().map(|p| p.predicted_time_s).sum();
    let steps = step_output(&run.ticks, o.machine, run.period_s, table)?;
    if o.json {
        let out = ProgramRunOut {
            schema_version: check::SCHEMA_VERSION,
            program: table.display().to_string(),
            period_s: run.period_s,
            paths: &run.paths,
            stops: &run.stops,
            blocks_executed: run.blocks_executed(),
            last_block: run.last_block(),
            machining_time_s: run.machining_time_s(),
            predicted_time_s: predicted,
            setpoints: run.ticks.len(),
            warnings: &run.file.warnings,
            check: reports.as_deref(),
            programmed_contour: programmed,
            steps,
            csv: o.csv.map(|p| p.display().to_string()),
            plot: o.plot.map(|p| p.display().to_string()),
        };
        outln!("{}", serde_json::to_string(&out)?);
    } else {
        let feed = run
            .paths
            .iter()
            .filter(|p| p.kind == planner_host::program::EntryKind::Feed)
            .count();
        outln!(
            "{}: program of {} paths ({} feed, {} rapid), {} program stops; {} blocks executed, the last LINE {}",
            table.display(),
            run.paths.len(),
            feed,
            run.paths.len() - feed,
            run.stops.len(),
            run.blocks_executed(),
            run.last_block().unwrap_or(0)
        );
        outln!(
            "  simulation at {} us: machining time {:.4} s (tables predict {:.4} s, {:+.3} %), {} setpoints",
            run.period_s * 1e6,
            run.machining_time_s(),
            predicted,
            100.0 * (run.machining_time_s() / predicted - 1.0),
            run.ticks.len()
        );
        for (i, p) in run.paths.iter().enumerate() {
            if i == planner_host::program::plan::SUMMARY_PATHS {
                outln!("  ... {} more paths (--json lists them all)", run.paths.len() - i);
                break;
            }
            let chk = reports.as_ref().map_or(String::new(), |r| {
                let r = &r[i];
                format!(
                    "  worst ratio {:.4}, contour {:.2e} mm{}",
                    r.ratios.named().iter().map(|(_, p)| p.ratio).fold(0.0, f64::max),
                    r.contour.max_mm,
                    if r.ok { "" } else { "  FAIL" }
                )
            });
            outln!(
                "  path {:>3}  LINE {}..{}  {:<5} {:>10.3} mm  {:>8.4} s (predicted {:.4} s){chk}",
                p.index,
                p.first_line,
                p.last_line,
                match p.kind {
                    planner_host::program::EntryKind::Rapid => "rapid",
                    _ => "feed",
                },
                p.length_mm,
                p.time_s,
                p.predicted_time_s
            );
        }
        for w in &run.file.warnings {
            outln!("  warning: {w}");
        }
        if let Some(p) = o.csv {
            outln!("  wrote {}", p.display());
        }
        if let Some(p) = o.plot {
            outln!("  wrote {}", p.display());
        }
        if let Some(r) = &reports {
            let worst = |f: &dyn Fn(&CheckReport) -> f64| r.iter().map(f).fold(0.0, f64::max);
            outln!(
                "check of every path against its curve and limits ({} ticks at rest around each): worst ratio {:.4} (vel {:.4}, acc {:.4}, jerk {:.4}, feed {:.4}, tacc {:.4}, tjerk {:.4}), contour {:.3e} mm; {}",
                r.first().map_or(0, |x| x.pad_rest),
                worst(&|x| x.ratios.named().iter().map(|(_, p)| p.ratio).fold(0.0, f64::max)),
                worst(&|x| x.ratios.vel.ratio),
                worst(&|x| x.ratios.acc.ratio),
                worst(&|x| x.ratios.jerk.ratio),
                worst(&|x| x.ratios.feed.ratio),
                worst(&|x| x.ratios.tacc.ratio),
                worst(&|x| x.ratios.tjerk.ratio),
                worst(&|x| x.contour.max_mm),
                if r.iter().all(|x| x.ok) { "pass" } else { "FAIL" }
            );
        }
        if let Some(r) = &steps {
            outln!("{}", step_text(r));
        }
        if let Some(c) = &programmed {
            outln!(
                "contour against the programmed geometry ({} setpoints): exact moves {:.3e} mm (allowed {:.0e}, LINE {}), moves under G64 P {:.3e} mm (allowed {:.3e}, LINE {}); feed against each block's F: ratio {:.4} ({:.3} of {:.3} mm/s, LINE {}); {}",
                c.setpoints,
                c.exact.distance_mm,
                sim_harness::programmed::EXACT_MM,
                c.exact.line,
                c.toleranced.distance_mm,
                c.toleranced.allowed_mm,
                c.toleranced.line,
                c.feed.ratio,
                c.feed.feed_mm_s,
                c.feed.programmed_mm_s,
                c.feed.line,
                if c.pass() { "pass" } else { "FAIL" }
            );
        }
    }
    if let Some(c) = programmed.filter(|c| !c.pass()) {
        return Err(Failure {
            code: EXIT_LIMIT,
            message: format!(
                "{}: a setpoint leaves the programmed path or its feed: {:.3e} mm at LINE {} (allowed {:.0e}), {:.3e} mm at LINE {} (allowed {:.3e}), feed {:.4} of F at LINE {} (allowed {})",
                table.display(),
                c.exact.distance_mm,
                c.exact.line,
                sim_harness::programmed::EXACT_MM,
                c.toleranced.distance_mm,
                c.toleranced.line,
                c.toleranced.allowed_mm,
                c.feed.ratio,
                c.feed.line,
                1.0 + sim_harness::programmed::FEED_TOL
            ),
        });
    }
    if let Some(r) = &reports {
        for (p, rep) in run.paths.iter().zip(r) {
            check_verdict(rep).map_err(|f| Failure {
                code: f.code,
                message: format!(
                    "{}: path {} (LINE {}..{}): {}",
                    table.display(),
                    p.index,
                    p.first_line,
                    p.last_line,
                    f.message
                ),
            })?;
        }
    }
    Ok(())
}

fn check_run(bytes: &[u8], res: &SimResult, tol: f64, pad_rest: usize) -> Result<CheckReport, Failure> {
    let table =
        firmware_core::Table::parse(bytes).map_err(|e| Failure::input(format!("table rejected: {e}")))?;
    let geometry = sim_harness::CurveGeometry::from_table(&table)
        .map_err(|e| Failure::input(format!("the table's NURBS is not usable for the check: {e}")))?;
    let cfg = CheckConfig {
        limits: res.limits,
        pad_rest,
        tol,
        ..CheckConfig::default()
    };
    check::check_trajectory(&geometry.curve, &Trajectory::from_ticks(&res.ticks), &cfg)
        .map_err(Failure::input)
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

fn demo(out: &Path) -> Result<(), Failure> {
    std::fs::create_dir_all(out).map_err(|e| format!("cannot create {}: {e}", out.display()))?;
    let curve = load_curve("butterfly")?;
    let cfg = PlanConfig {
        sampling: Sampling::Len,
        density_per_mm: 1.0,
        limits: limits::TABLE1,
        ..PlanConfig::default()
    };
    let planned = plan::plan_curve(&curve, &cfg).map_err(plan_failure)?;
    let arc = ArcLength::new(&curve);
    let check = verify::dense_check_ends(
        &curve,
        &arc,
        &planned.q_knots,
        &planned.q_ctrl,
        planned.ends.as_ref(),
        &cfg.limits,
        None,
        20,
    );
    outln!("== plan");
    out!("{}", planned.summary(Some(&check)));

    let bin = out.join("butterfly.bin");
    sim_harness::csv::write_atomic(&bin, &planned.table_bytes)?;
    let res = run_table(&planned.table_bytes, &SimConfig::default())?;
    outln!("== simulation");
    out!("{}", res.summary());
    let csv = out.join("butterfly.csv");
    sim_harness::csv::write_csv(&csv, &res.ticks)?;
    let png = out.join("butterfly_feed.png");
    write_plot(&png, &res, "Butterfly")?;
    outln!("== wrote {}, {}, {}", bin.display(), csv.display(), png.display());
    Ok(())
}

fn override_report(
    names: &[String],
    out: &Path,
    latency_ms: f64,
    compute_ms: f64,
    trident: Option<&str>,
    period_us: f64,
) -> Result<(), Failure> {
    use sim_harness::report::overrides as orep;
    std::fs::create_dir_all(out).map_err(|e| format!("cannot create {}: {e}", out.display()))?;
    let butterfly = load_curve("butterfly")?;
    let trident = load_curve(trident.unwrap_or("trident"))?;
    let link = sim_harness::scenario::LinkConfig {
        down_latency_s: latency_ms * 1e-3,
        up_latency_s: latency_ms * 1e-3,
        compute_budget_s: compute_ms * 1e-3,
        ..Default::default()
    };
    let all = orep::catalogue(&butterfly, Some(&trident), link);
    for n in names {
        if !all.iter().any(|s| s.name == n) {
            return Err(Failure::usage(format!(
                "unknown scenario {n:?} (known: {})",
                all.iter().map(|s| s.name).collect::<Vec<_>>().join(", ")
            )));
        }
    }
    let mut md = format!(
        "# Feedrate override and feed hold scenarios\n\nMade by `cargo run --release -p sim-harness --bin feedsim -- override{}` \
         (one-way link latency {latency_ms} ms, host compute budget {compute_ms} ms in the timeline, servo period {period_us} us). \
         Ratios are the commanded setpoints' largest ratio to each limit with the machine at rest before and after \
         (`--pad-rest`), by feedsim's own stencils; CI checks every CSV with `feedsim check --pad-rest 50`.\n\n{}\n",
        names.iter().map(|n| format!(" {n}")).collect::<String>(),
        orep::TABLE_HEAD
    );
    let mut notes = String::new();
    for spec in all
        .iter()
        .filter(|s| names.is_empty() || names.iter().any(|n| n == s.name))
    {
        eprintln!("feedsim override: {} ...", spec.name);
        let run = orep::run_spec(spec, period_us * 1e-6, true)?;
        let (row, files) = orep::write_run(out, &run)?;
        outln!("{row}");
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
                orep::median_max(&dist).map_or("–".into(), |(a, b)| format!("{a:.1} / {b:.1}")),
                orep::median_max(&time).map_or("–".into(), |(a, b)| format!("{a:.2} / {b:.2}")),
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
    outln!("wrote {}", out.join("README.md").display());
    Ok(())
}
