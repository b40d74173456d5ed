//! The fuzz corpus as a regression test on stable Rust: every committed input
//! of `fuzz/corpus/<target>/` and `fuzz/regressions/<target>/` goes through
//! the same corruption code and invariant check as the fuzz targets
//! (`fuzz/src/mutate.rs`, included here), so `cargo test --workspace` guards
//! what the fuzzer found without nightly or libFuzzer. See docs/robustness.md.

#[path = "../../fuzz/src/mutate.rs"]
#[allow(dead_code)]
mod mutate;

#[path = "../../fuzz/src/stream.rs"]
#[allow(dead_code)]
mod stream;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use firmware_core::dry_run::{dry_run, Outcome};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn files(target: &str) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for dir in ["corpus", "regressions"] {
        let Ok(rd) = std::fs::read_dir(root().join("fuzz").join(dir).join(target)) else {
            continue;
        };
        out.extend(
            rd.filter_map(|e| e.ok())
                .map(|e| e.path())
                .filter(|p| p.is_file()),
        );
    }
    out.sort();
    out
}

/// The outcome's name: `Refused(SuBreak)`, `Done`, `Fault(Stalled)`, ….
fn name(o: &Outcome) -> String {
    let s = format!("{o:?}");
    let cut = |s: &str| s.split([' ', '{', ')']).next().unwrap_or("").to_string();
    match s.split_once('(') {
        Some((head, rest)) => format!("{head}({})", cut(rest)),
        None => s,
    }
}

fn replay(target: &str, prepare: fn(&[u8]) -> Vec<u8>) -> BTreeMap<String, usize> {
    let inputs = files(target);
    assert!(!inputs.is_empty(), "no corpus for {target}");
    let mut tally = BTreeMap::new();
    for path in &inputs {
        let data = std::fs::read(path).unwrap();
        let table = prepare(&data);
        let r = std::panic::catch_unwind(|| mutate::check(&table))
            .unwrap_or_else(|_| panic!("{target}: {} breaks an invariant", path.display()));
        *tally.entry(name(&r.outcome)).or_insert(0) += 1;
    }
    println!("{target}: {} inputs: {tally:?}", inputs.len());
    tally
}

#[test]
fn table_parse_corpus_replays_clean() {
    let tally = replay("table_parse", |d| d.to_vec());
    assert!(
        tally.get("Done").copied().unwrap_or(0) >= 1,
        "the valid seeds run to the end"
    );
}

#[test]
fn table_mutate_corpus_replays_clean() {
    let tally = replay("table_mutate", mutate::apply);
    assert!(tally.keys().any(|k| k.starts_with("Refused")));
}

#[test]
fn stream_link_corpus_replays_clean() {
    let inputs = files("stream_link");
    assert!(!inputs.is_empty(), "no corpus for stream_link");
    let mut accepted = 0;
    for path in &inputs {
        let data = std::fs::read(path).unwrap();
        let r = std::panic::catch_unwind(|| stream::check_stream(&data))
            .unwrap_or_else(|_| panic!("stream_link: {} breaks an invariant", path.display()));
        println!("stream_link: {}: {r:?}", path.display());
        accepted += r.accepted;
    }
    assert!(accepted >= 1, "the seed streams reach the ring");
}

#[test]
fn seeds_are_valid_and_run_to_the_end() {
    for (i, seed) in mutate::SEEDS.iter().enumerate() {
        let r = dry_run(seed, mutate::PERIOD_S, 1_000_000).unwrap();
        assert_eq!(
            r.outcome,
            Outcome::Done,
            "seed {i} no longer a valid table: regenerate with fuzz/seeds/make.sh"
        );
        println!(
            "seed {i}: {} ticks, max step {:.6} mm = {:.4} of the bound, max feed {:.3} mm/s",
            r.ticks,
            r.max_step_mm,
            r.max_step_mm / r.step_bound_mm,
            r.max_feed_mm_s
        );
    }
}

#[test]
fn lowered_vbar_regression_is_refused() {
    // vbar of the line seed halved three times (166 -> 20.75 mm/s) behind a
    // fresh CRC: the seed's q (feed up to ~55 mm/s) is then above
    // Q_VBAR_SLACK · vbar², which Table::parse refuses (the bug table_mutate
    // found on the v2 format, crash-cb99f84c…; re-expressed for the v3 seeds).
    let path = root().join("fuzz/regressions/table_mutate/vbar-lowered-v3");
    let table = mutate::apply(&std::fs::read(path).unwrap());
    assert!(matches!(
        firmware_core::Table::parse(&table),
        Err(firmware_core::TableError::QAboveVbar { .. })
    ));
}
