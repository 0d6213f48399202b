#!/usr/bin/env bash
# The triaxial test's speed at the paper's scale: on a specimen of `make paper-specimens`
# (default out/paper/ip-1.spec.jsonl), the consolidation timed in full, then loading timed to
# the first frame at or past STRAIN (default 0.01) of axial strain (frames come every 0.5 %),
# and the whole test to 15 % at the default rate projected from that loading rate of steps;
# with where a step's time goes. Beside it, in the same run, the engine on the same specimen
# in its rigid cylinder (`dem --steps DEM_STEPS` on the pack state, default 300): a loading
# step's time over the engine's, the membrane's price.
# Usage: pipelines/bench-triax.sh [SPEC [STRAIN]]   (triax and dem on PATH)
set -euo pipefail
spec=${1:-out/paper/ip-1.spec.jsonl} strain=${2:-0.01}
[ -f "$spec" ] || { echo "bench-triax: no $spec (make paper-specimens); skipped"; exit 0; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
start=$(date +%s.%N)
triax --stop-at 0 < "$spec" > "$tmp/start.jsonl" 2> "$tmp/consolidation.log"
mid=$(date +%s.%N)
triax --stop-at "$strain" < "$tmp/start.jsonl" > "$tmp/rest.jsonl" 2> "$tmp/loading.log"
end=$(date +%s.%N)
dem --steps "${DEM_STEPS:-300}" < "$spec" > /dev/null 2> "$tmp/dem.log"
step0=$(grep -o '"step":[0-9]*' "$tmp/start.jsonl" | tail -1 | cut -d: -f2)
steps_c=$(grep -o '"consolidation_steps":[0-9]*' "$tmp/start.jsonl" | tail -1 | cut -d: -f2)
step1=$(grep -o '"step":[0-9]*' "$tmp/rest.jsonl" | tail -1 | cut -d: -f2)
dt=$(grep -o '"dt":[0-9.e-]*' "$tmp/start.jsonl" | head -1 | cut -d: -f2)
rate=$(grep -o '"rate":[0-9.e-]*' "$tmp/start.jsonl" | head -1 | cut -d: -f2)
# dem's own timing line: "N steps of M bodies on K threads in T s".
dem_steps=$(sed -n 's/.*dem: \([0-9]*\) steps of .* in \([0-9.]*\) s.*/\1/p' "$tmp/dem.log")
dem_secs=$(sed -n 's/.*dem: \([0-9]*\) steps of .* in \([0-9.]*\) s.*/\2/p' "$tmp/dem.log")
awk -v c0="$start" -v c1="$mid" -v c2="$end" -v s0="$step0" -v sc="$steps_c" \
    -v s1="$step1" -v dt="$dt" -v rate="$rate" -v strain="$strain" -v spec="$spec" \
    -v dn="$dem_steps" -v ds="$dem_secs" 'BEGIN {
  c = c1 - c0; l = c2 - c1; per = (s1 - s0) / l;
  full = 0.15 / rate / dt;
  printf "bench-triax %s: consolidation %d steps in %.0f s; loading %d steps to %s in %.0f s (%.1f steps/s)\n", spec, sc, c, s1 - s0, strain, l, per;
  printf "bench-triax: projected test to 15 %% at %s /s: %.0f loading steps, %.0f min with the consolidation\n", rate, full, (c + full / per) / 60;
  printf "bench-triax: the same specimen in its rigid cylinder (dem): %.1f steps/s; a loading step costs %.2fx an engine step\n", dn / ds, (dn / ds) / per }'
grep "step time" "$tmp/loading.log" | sed 's/^.*triax:/bench-triax: loading/'
