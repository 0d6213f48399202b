#!/usr/bin/env bash
# Two `dem` binaries against each other on one bed, in alternating pairs: the way to see a
# change of a few per cent on a VM whose speed moves by more than that within minutes (the
# same binary against itself gave a median ratio of 1.012, quartiles 0.976-1.055, over 16
# pairs of the 5000 I_P bed on 2 threads; docs/performance.md).
#
# Each pair runs A then B, or B then A (the order alternates), `--renumber --steps STEPS` from
# the bed, and takes the time `dem` reports for its steps; the line printed is the median of
# the per-pair ratios B / A with the quartiles, and each binary's least and mean time. Both
# must write the same bytes (checked on the first pair): a speed change must not change the
# physics.
#
# Usage: pipelines/ab-dem.sh BED.jsonl A B [PAIRS [STEPS [THREADS]]]
#   e.g. pipelines/ab-dem.sh out/bench/nine5000.jsonl /tmp/dem-old target/release/dem 16 200 2
set -euo pipefail
if [ $# -lt 3 ]; then
  sed -n 's/^# Usage: /usage: /p' "$0" >&2
  exit 2
fi
bed=$1 a=$2 b=$3 pairs=${4:-16} steps=${5:-200} threads=${6:-2}
[ -f "$bed" ] || { echo "ab-dem: no bed $bed" >&2; exit 1; }
for bin in "$a" "$b"; do
  [ -x "$bin" ] || { echo "ab-dem: $bin is not an executable" >&2; exit 1; }
done
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# Seconds of `dem`'s own timing line ("N steps of M bodies [on K threads] in T s"); the state it wrote is
# left in $tmp/OUT.
run() {
  RAYON_NUM_THREADS=$threads "$1" --renumber --steps "$steps" < "$bed" > "$tmp/$2" 2> "$tmp/err"
  sed -n 's/^\(\[.*\] \)\{0,1\}dem: .* steps of .* bodies\( on [0-9]* threads\{0,1\}\)\{0,1\} in \([0-9.]*\) s.*/\3/p' "$tmp/err"
}
for k in $(seq "$pairs"); do
  if [ $((k % 2)) = 1 ]; then ta=$(run "$a" a.out); tb=$(run "$b" b.out); else tb=$(run "$b" b.out); ta=$(run "$a" a.out); fi
  if [ "$k" = 1 ] && ! cmp -s "$tmp/a.out" "$tmp/b.out"; then
    echo "ab-dem: A and B write different bytes" >&2
    exit 1
  fi
  echo "$ta $tb"
done > "$tmp/times"
awk '{ print $2 / $1 }' "$tmp/times" | sort -g > "$tmp/ratios"
n=$(wc -l < "$tmp/ratios")
at() { sed -n "$1p" "$tmp/ratios"; }
median=$(awk -v n="$n" '{ r[NR] = $1 } END { print (n % 2) ? r[(n + 1) / 2] : (r[n / 2] + r[n / 2 + 1]) / 2 }' "$tmp/ratios")
stats() { awk -v c="$1" '{ s += $c; if (NR == 1 || $c < m) m = $c } END { printf "least %.3f s, mean %.3f s", m, s / NR }' "$tmp/times"; }
printf 'ab-dem: %s, %s steps, %s threads, %s pairs: B / A median %.3f (quartiles %.3f-%.3f); A %s; B %s\n' \
  "$(basename "$bed")" "$steps" "$threads" "$n" "$median" "$(at $((n / 4 + 1)))" "$(at $((3 * n / 4)))" \
  "$(stats 1)" "$(stats 2)"
