#!/usr/bin/env bash
# The fuzzers of the tools' readers: for each target of fuzz/ (obj_stream, dem_state,
# peer_scene, plot_csv), libFuzzer through cargo fuzz on the nightly toolchain for SECONDS
# (default 3600) or RUNS executions (default 10 000 000), whichever ends first, with limits per
# input (10 s, 2 GiB, 64 KiB long). The corpus grows in fuzz/corpus/TARGET (minimised at the
# end: commit its inputs of 8 KiB or less, which keep the repository small), crashes land
# in fuzz/artifacts/TARGET and are moved to fuzz/regressions/TARGET, which the test suite
# replays (shared/tests/fuzz_corpus.rs).
# Installs cargo-fuzz from crates.io when it is missing. Prints each target's executions,
# coverage and crashes, also appended to fuzz/report.txt.
# Usage: pipelines/fuzz.sh [SECONDS [RUNS [TARGET...]]]
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-3600} runs=${2:-10000000}
shift $(( $# < 2 ? $# : 2 ))
targets=${*:-obj_stream dem_state peer_scene plot_csv}
command -v cargo-fuzz > /dev/null || cargo install --locked cargo-fuzz
rustup toolchain list | grep -q '^nightly' || rustup toolchain install nightly --profile minimal

for t in $targets; do
  mkdir -p "fuzz/corpus/$t" "fuzz/regressions/$t"
  log=$(mktemp)
  # libFuzzer stops at the first crash or timeout, which it writes to fuzz/artifacts/TARGET:
  # fix it, keep it (below) and run again.
  (cd fuzz && cargo +nightly fuzz run "$t" "corpus/$t" "seeds/$t" -- \
      -max_total_time="$seconds" -runs="$runs" -timeout=10 -rss_limit_mb=2048 \
      -max_len=65536 -print_final_stats=1) > "$log" 2>&1 || true
  execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' | tail -1)
  cov=$(grep -o 'cov: [0-9]* ft: [0-9]*' "$log" | tail -1)
  crashes=0
  for a in fuzz/artifacts/"$t"/*; do
    [ -e "$a" ] || continue
    mv -f "$a" "fuzz/regressions/$t/"
    crashes=$((crashes + 1))
  done
  (cd fuzz && cargo +nightly fuzz cmin "$t" "corpus/$t" > /dev/null 2>&1) || true
  line="$t: ${execs:-?} executions in at most $seconds s, ${cov:-no coverage line}, $crashes crash inputs (fuzz/regressions/$t), corpus $(ls "fuzz/corpus/$t" | wc -l) inputs"
  echo "$line" | tee -a fuzz/report.txt
  grep -m3 -E 'panicked|ERROR: libFuzzer|SUMMARY' "$log" || true
  rm -f "$log"
done
