#!/usr/bin/env bash
# DEM engine throughput, side by side in one run: the peer benchmark's settled 500-particle bed
# (../shared/peers/yade, Yade's own settled state) with 1 and 2 threads, and the 2000-particle
# scene's first steps (a loose cloud: broad phase and wall checks). Results: docs/bench.md.
# Usage: pipelines/bench-dem.sh [STEPS]   (default 200)
set -euo pipefail
steps=${1:-200}
peers=${PEERS:-../shared/peers/yade}
if [ ! -f "$peers/scene_500.txt" ]; then
  echo "bench-dem: no peer scenes in $peers (set PEERS=DIR); skipped"
  exit 0
fi
echo "machine: $(nproc) cores; dem on the peer scenes, $steps steps each"
row() {  # label, threads, dem arguments...
  local label=$1 th=$2; shift 2
  local line
  line=$(RAYON_NUM_THREADS=$th dem "$@" 2>&1 >/dev/null | grep 'particle-steps/s')
  printf '%-44s %s thread(s)  %s\n' "$label" "$th" "$line"
}
for th in 1 2; do
  row "settled 500 bed (Yade's state)" "$th" --import-peer "$peers/scene_500.txt" \
    --peer-state "$peers/settled_500_state.txt" --steps "$steps"
done
for th in 1 2; do
  row "2000-particle cloud, first steps" "$th" --import-peer "$peers/scene_2000.txt" --steps "$steps"
done
