//! The full curve-family sweep: generate random toolpaths, plan each at
//! every sampling and density, run the tables through the firmware and
//! check the setpoints; print the worst ratio per family and limit.
//!
//! ```text
//! cargo run --release -p e2e-tests --example curve_family -- --curves 200 --seed 1 --json out.jsonl
//! ```
//!
//! `--list` prints the generated curves without planning them;
//! `--write-curves DIR` writes each as a curve JSON file for `feedplan`;
//! `--summarize A.jsonl B.jsonl …` prints the summary of earlier runs'
//! `--json` output (a sweep run in parts, `--first`/`--curves`, or on
//! several machines) without running anything.

use std::io::Write;
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

use clap::Parser;
use e2e_tests::curve_family::sweep::{self, Row, Run, Summary};
use e2e_tests::curve_family::{generate, Case};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// Sweep the seeded family of random toolpaths through planner, firmware and checker.
#[derive(Parser, Debug)]
struct Args {
    /// How many curves (indices 0 .. N of the family).
    #[arg(long, default_value_t = 200)]
    curves: usize,
    /// First curve index.
    #[arg(long, default_value_t = 0)]
    first: usize,
    /// The family's seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Sampling densities, points per mm.
    #[arg(long, value_delimiter = ',', default_value = "0.5,1,2")]
    densities: Vec<f64>,
    /// Samplings (PAR, LEN, ADA).
    #[arg(long, value_delimiter = ',', default_value = "PAR,LEN,ADA")]
    samplings: Vec<String>,
    /// Worker threads.
    #[arg(long, default_value_t = 1)]
    jobs: usize,
    /// Write one JSON object per run to this file (JSON Lines).
    #[arg(long)]
    json: Option<PathBuf>,
    /// Write the summary tables (Markdown) to this file too.
    #[arg(long)]
    markdown: Option<PathBuf>,
    /// Only list the generated curves.
    #[arg(long)]
    list: bool,
    /// Write every generated curve as a curve JSON file into this folder.
    #[arg(long)]
    write_curves: Option<PathBuf>,
    /// Summarise these `--json` files instead of running.
    #[arg(long, num_args = 1..)]
    summarize: Vec<PathBuf>,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

fn curve_json(c: &Case) -> String {
    serde_json::json!({
        "name": c.curve.name,
        "degree": c.curve.degree,
        "weights": c.curve.weights,
        "knots": c.curve.knots,
        "control_points": c.curve.points,
    })
    .to_string()
}

fn summarize(files: &[PathBuf]) -> Result<Vec<Row>, Box<dyn std::error::Error>> {
    let mut rows = Vec::new();
    for f in files {
        let text = std::fs::read_to_string(f)?;
        let lines: Vec<&str> = text.lines().filter(|l| !l.trim().is_empty()).collect();
        for (i, line) in lines.iter().enumerate() {
            let v: serde_json::Value = match serde_json::from_str(line) {
                Ok(v) => v,
                // the last line of a sweep still running or stopped may be cut short
                Err(e) if i + 1 == lines.len() => {
                    eprintln!("{}:{}: skipped, cut short ({e})", f.display(), i + 1);
                    continue;
                }
                Err(e) => return Err(e.into()),
            };
            rows.push(
                Row::from_json(&v)
                    .ok_or_else(|| format!("{}:{}: not a curve_family run", f.display(), i + 1))?,
            );
        }
    }
    // job order: curve, then sampling, then density
    let order = |r: &Row| sweep::samplings().iter().position(|s| s.0 == r.sampling);
    rows.sort_by(|a, b| {
        (a.index, order(a))
            .cmp(&(b.index, order(b)))
            .then(a.density.total_cmp(&b.density))
    });
    Ok(rows)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = Args::parse();
    if !args.summarize.is_empty() {
        let rows = summarize(&args.summarize)?;
        let curves: std::collections::BTreeSet<usize> = rows.iter().map(|r| r.index).collect();
        let md = format!(
            "{} curves, {} runs\n\n{}",
            curves.len(),
            rows.len(),
            Summary::new(&rows).markdown()
        );
        print!("{md}");
        if let Some(p) = &args.markdown {
            std::fs::write(p, &md)?;
        }
        return Ok(());
    }
    let cases: Vec<Case> = (args.first..args.first + args.curves)
        .map(|i| generate(args.seed, i))
        .collect();
    if let Some(dir) = &args.write_curves {
        std::fs::create_dir_all(dir)?;
        for c in &cases {
            std::fs::write(dir.join(format!("{}.json", c.curve.name)), curve_json(c))?;
        }
    }
    if args.list {
        for c in &cases {
            println!(
                "{:4} {:15} deg {} {} ctrl {:5} L {:8.1} mm redraws {}",
                c.index,
                c.family.name(),
                c.curve.degree,
                if c.space { "3-D" } else { "2-D" },
                c.curve.points.len(),
                c.length_mm,
                c.redraws
            );
        }
        return Ok(());
    }
    let samplings: Vec<_> = sweep::samplings()
        .into_iter()
        .filter(|(n, _)| args.samplings.iter().any(|s| s.eq_ignore_ascii_case(n)))
        .collect();
    let jobs: Vec<(usize, usize, f64)> = (0..cases.len())
        .flat_map(|c| {
            let d = &args.densities;
            (0..samplings.len()).flat_map(move |s| d.iter().map(move |&x| (c, s, x)))
        })
        .collect();

    let bar = ProgressBar::new(jobs.len() as u64);
    if args.quiet {
        bar.set_draw_target(ProgressDrawTarget::hidden());
    }
    bar.set_style(
        ProgressStyle::with_template("{elapsed_precise} [{bar:40}] {pos}/{len} runs, {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    let json_out = match &args.json {
        Some(p) => Some(Mutex::new(std::io::BufWriter::new(std::fs::File::create(p)?))),
        None => None,
    };
    let next = AtomicUsize::new(0);
    let over = AtomicUsize::new(0);
    let results: Mutex<Vec<(usize, Run)>> = Mutex::new(Vec::with_capacity(jobs.len()));
    let t0 = Instant::now();
    std::thread::scope(|scope| {
        for _ in 0..args.jobs.max(1) {
            scope.spawn(|| loop {
                let k = next.fetch_add(1, Ordering::Relaxed);
                let Some(&(c, s, d)) = jobs.get(k) else { break };
                let run = sweep::run(&cases[c], samplings[s], d);
                if run.over() {
                    over.fetch_add(1, Ordering::Relaxed);
                }
                if let Some(w) = &json_out {
                    if let Ok(mut w) = w.lock() {
                        let _ = writeln!(w, "{}", run.json_line()).and_then(|_| w.flush());
                    }
                }
                bar.set_message(format!(
                    "{} over 1.005, {}",
                    over.load(Ordering::Relaxed),
                    run.curve
                ));
                bar.inc(1);
                if let Ok(mut r) = results.lock() {
                    r.push((k, run));
                }
            });
        }
    });
    bar.finish_and_clear();
    if let Some(w) = json_out {
        w.into_inner()?.flush()?;
    }
    let mut results = results.into_inner()?;
    results.sort_by_key(|(k, _)| *k);
    let runs: Vec<Run> = results.into_iter().map(|(_, r)| r).collect();
    let rows: Vec<Row> = runs.iter().map(Row::from_run).collect();
    let summary = Summary::new(&rows);
    let md = format!(
        "{} curves (seed {}, indices {}..{}), samplings {}, densities {:?} points/mm: {} runs in {:.0} s\n\n{}",
        cases.len(),
        args.seed,
        args.first,
        args.first + args.curves,
        samplings.iter().map(|s| s.0).collect::<Vec<_>>().join(","),
        args.densities,
        runs.len(),
        t0.elapsed().as_secs_f64(),
        summary.markdown()
    );
    print!("{md}");
    if let Some(p) = &args.markdown {
        std::fs::write(p, &md)?;
    }
    Ok(())
}
