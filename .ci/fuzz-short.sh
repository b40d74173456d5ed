#!/usr/bin/env bash
# Short fuzz run of the table parser and the chunk stream (docs/robustness.md).
#
# 1. Replays the committed corpus (fuzz/corpus, fuzz/regressions) on stable
#    Rust through the same invariant check (tests/tests/fuzz_corpus.rs).
# 2. Fuzzes each target for FUZZ_SECONDS (default 60) with cargo-fuzz
#    (libFuzzer), one worker, starting from the committed corpus; new inputs go
#    to a scratch directory, so the repository is not modified.
# Exits non-zero on a crash, panic, hang (> 5 s an input) or broken invariant.
# Installs the nightly toolchain and cargo-fuzz if missing; if they cannot be
# installed, step 2 is skipped with a warning (fatal with FUZZ_REQUIRED=1).
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TERM_COLOR=never
SECS=${FUZZ_SECONDS:-60}
TOOLCHAIN=${FUZZ_TOOLCHAIN:-nightly}

# (FUZZ_REPLAY=0: the caller has replayed it already, e.g. in `cargo test
# --workspace`, which runs tests/tests/fuzz_corpus.rs)
if [ "${FUZZ_REPLAY:-1}" = 1 ]; then
  echo "== fuzz corpus replay (stable)"
  cargo test -p e2e-tests --test suite fuzz_corpus::
fi

have_tools() {
  rustup run "$TOOLCHAIN" rustc --version >/dev/null 2>&1 && cargo fuzz --version >/dev/null 2>&1
}
if ! have_tools; then
  echo "== installing $TOOLCHAIN and cargo-fuzz"
  rustup run "$TOOLCHAIN" rustc --version >/dev/null 2>&1 \
    || rustup toolchain install "$TOOLCHAIN" --profile minimal || true
  cargo fuzz --version >/dev/null 2>&1 || cargo install cargo-fuzz --locked || true
fi
if ! have_tools; then
  echo "warning: no $TOOLCHAIN toolchain or cargo-fuzz: short fuzz run skipped" >&2
  [ "${FUZZ_REQUIRED:-0}" = 1 ] && exit 1
  exit 0
fi

cd fuzz
for t in table_parse table_mutate stream_link; do
  echo "== cargo fuzz run $t for ${SECS} s"
  work=$(mktemp -d)
  trap 'rm -rf "$work"' EXIT
  dirs=("$work" "corpus/$t")
  [ -d "regressions/$t" ] && dirs+=("regressions/$t")
  # -s none: firmware-core is forbid(unsafe) safe Rust, so AddressSanitizer
  # adds cost, not findings; -a keeps overflow checks and debug assertions.
  cargo "+$TOOLCHAIN" fuzz run -O -a -s none "$t" "${dirs[@]}" -- \
    -max_total_time="$SECS" -timeout=5 -rss_limit_mb=2048 -print_final_stats=1 2>&1 \
    | grep -vE '^#[0-9]+[[:space:]]+(NEW|REDUCE|pulse)' || exit "${PIPESTATUS[0]}"
  rm -rf "$work"
done
echo "== fuzz-short passed"
