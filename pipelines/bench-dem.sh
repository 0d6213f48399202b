#!/usr/bin/env bash
# DEM engine throughput, side by side in one run, with 1 and 2 threads:
# - the peer benchmark's 500-particle bed settled under our own law at the paper's stiffness
#   (kn = 1e8 N/m; made once by pipelines/settle-peer.sh from Yade's settled state, about
#   10 minutes, kept in out/bench/);
# - Yade's own settled state loaded as it is (its volumetric law leaves overlaps of 0.23 mm:
#   deep contacts under our law, so this measures deep-overlap cost, not a settled bed);
# - the 2000-particle scene's first steps (a loose cloud: broad phase and wall checks).
# Contacts per particle are printed with each row. Results: docs/bench.md.
# Usage: pipelines/bench-dem.sh [STEPS]   (default 200; dem must be on PATH)
set -euo pipefail
steps=${1:-200}
peers=${PEERS:-../shared/peers/yade}
out=${OUT:-out}/bench
if [ ! -f "$peers/scene_500.txt" ]; then
  echo "bench-dem: no peer scenes in $peers (set PEERS=DIR); skipped"
  exit 0
fi
mkdir -p "$out"
bed=$out/bed500.jsonl
if [ ! -f "$bed" ]; then
  echo "bench-dem: settling the 500 bed at kn = 1e8 N/m into $bed (once, ~10 min)"
  PEERS=$peers "$(dirname "$0")/settle-peer.sh" 500 "$bed.tmp" 2>"$out/settle.log"
  mv "$bed.tmp" "$bed"
fi
echo "machine: $(nproc) cores; dem, $steps timed steps each"
row() {  # label, threads, dem arguments... (the scene on stdin)
  local label=$1 th=$2; shift 2
  local line
  line=$(RAYON_NUM_THREADS=$th dem "$@" 2>&1 >/dev/null | grep 'particle-steps/s')
  printf '%-40s %s thread(s)  %s\n' "$label" "$th" "$line"
}
for th in 1 2; do
  row "500 bed settled at kn = 1e8 (ours)" "$th" --steps "$steps" < "$bed"
done
for th in 1 2; do
  row "500 bed, Yade's state (deep overlaps)" "$th" --import-peer "$peers/scene_500.txt" \
    --peer-state "$peers/settled_500_state.txt" --steps "$steps"
done
for th in 1 2; do
  row "2000-particle cloud, first steps" "$th" --import-peer "$peers/scene_2000.txt" --steps "$steps"
done
