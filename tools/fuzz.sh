#!/usr/bin/env bash
# Bounded fuzzing of every file format (tools/fuzz, cargo fuzz with libFuzzer): each target runs
# SECONDS (default 15) from the seeds in tools/fuzz/corpus/<target> plus what earlier runs on
# this machine found; any panic, crash, hang (> 10 s per input) or > 2 GB of memory fails.
# Findings land in tools/fuzz/artifacts/<target>/: fix the cause, then keep the input in
# tools/fuzz/regressions/<target>/ (tests/fuzz_regressions.rs replays it).
# Stable Rust, no sanitizer (safe Rust: panics, aborts, hangs and memory are what we look for).
set -euo pipefail
cd "$(dirname "$0")/.."
secs="${1:-15}"
command -v cargo-fuzz >/dev/null 2>&1 || cargo install -q cargo-fuzz --locked
# Instrumented builds are kept between runs (a clean clone would rebuild everything, ~7 min).
export CARGO_TARGET_DIR="${RELIT_FUZZ_TARGET:-$HOME/.cache/relit/fuzz-target}"
cargo fuzz build --fuzz-dir tools/fuzz -s none
work="$HOME/.cache/relit/fuzz-corpus"
# The targets write their inputs as files under $TMPDIR: give them a directory that goes away.
scratch="$(mktemp -d)"
trap 'rm -rf "$scratch"' EXIT
for t in scene_json colmap colmap_bin transforms bundler mesh_obj mesh_ply image camera_path weights; do
  mkdir -p "$work/$t"
  log="$(mktemp)"
  if ! TMPDIR="$scratch" cargo fuzz run --fuzz-dir tools/fuzz -s none "$t" "$work/$t" "tools/fuzz/corpus/$t" -- \
      -max_total_time="$secs" -timeout=10 -rss_limit_mb=2048 >"$log" 2>&1; then
    grep -v '^#' "$log" | tail -40
    echo "fuzz: $t failed (input in tools/fuzz/artifacts/$t/)" >&2
    exit 1
  fi
  echo "fuzz: $t $(grep -o 'Done [0-9]* runs in [0-9]* second(s)' "$log"), corpus $(ls "$work/$t" | wc -l) inputs"
  rm -f "$log"
done
