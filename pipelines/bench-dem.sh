#!/usr/bin/env bash
# DEM engine throughput, side by side in one run, with 1 and 2 threads:
# - the peer benchmark's 500-particle bed settled under our own law at the paper's stiffness
#   (kn = 1e8 N/m; made once by pipelines/settle-peer.sh from Yade's settled state, about
#   10 minutes, kept in out/bench/);
# - Yade's own settled state loaded as it is (its volumetric law leaves overlaps of 0.23 mm:
#   deep contacts under our law, so this measures deep-overlap cost, not a settled bed);
# - the 2000-particle scene settled the same way (made once, about 40 minutes; BED2000=0 skips);
# - the 500 bed with every particle turned into its Ab_3 hull (`dem --abrade 3`), settled
#   the same way (made once, about an hour; BEDAB3=0 skips);
# - the 2000-particle scene's first steps (a loose cloud: broad phase and wall checks);
# - Yade itself on its own settled 500 bed, when `yade` is installed (settled once, 16 minutes).
# Each of our rows also prints where the step time goes and the peak resident memory.
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
bed2000=$out/bed2000.jsonl
if [ ! -f "$bed2000" ] && [ "${BED2000:-1}" = 1 ]; then
  echo "bench-dem: settling the 2000 scene at kn = 1e8 N/m into $bed2000 (once, ~40 min; BED2000=0 skips)"
  PEERS=$peers "$(dirname "$0")/settle-peer.sh" 2000 "$bed2000.tmp" 2>"$out/settle2000.log"
  mv "$bed2000.tmp" "$bed2000"
fi
bedab3=$out/ab3bed500.jsonl
if [ ! -f "$bedab3" ] && [ "${BEDAB3:-1}" = 1 ]; then
  echo "bench-dem: settling the 500 bed as Ab_3 hulls at kn = 1e8 N/m into $bedab3 (once, about an hour; BEDAB3=0 skips)"
  PEERS=$peers ABRADE=3 "$(dirname "$0")/settle-peer.sh" 500 "$bedab3.tmp" 2>"$out/settle-ab3.log"
  mv "$bedab3.tmp" "$bedab3"
fi
# Yade on the same machine in the same run, when it is installed: its own settled 500 bed
# (the peer README's recipe, about 16 minutes once), then the same timed steps from it.
yade_state=$out/yade-settled500.xml.bz2
if command -v yade >/dev/null && [ ! -f "$yade_state" ]; then
  echo "bench-dem: settling the 500 scene in Yade into $yade_state (once, ~16 min)"
  yade -j 2 -n -f2 -x "$peers/run_yade.py" "$peers/scene_500.txt" --shape poly --warmup 0 \
    --settle 2.0 --settle-wall 840 --save "$yade_state" --steps 10 >"$out/yade-settle.log" 2>&1
fi
echo "machine: $(nproc) cores; dem, $steps timed steps each"
row() {  # label, threads, dem arguments... (the scene on stdin)
  local label=$1 th=$2; shift 2
  local log
  log=$(RAYON_NUM_THREADS=$th dem "$@" 2>&1 >/dev/null)
  printf '%-40s %s thread(s)  %s\n' "$label" "$th" "$(grep 'particle-steps/s' <<<"$log")"
  grep -E 'step time|peak resident' <<<"$log" | sed 's/^/      /'
}
for th in 1 2; do
  row "500 bed settled at kn = 1e8 (ours)" "$th" --steps "$steps" < "$bed"
done
if [ -f "$bed2000" ]; then
  for th in 1 2; do
    row "2000 bed settled at kn = 1e8 (ours)" "$th" --steps "$steps" < "$bed2000"
  done
fi
if [ -f "$bedab3" ]; then
  for th in 1 2; do
    row "500 bed of Ab_3 hulls at kn = 1e8 (ours)" "$th" --steps "$steps" < "$bedab3"
  done
fi
for th in 1 2; do
  row "500 bed, Yade's state (deep overlaps)" "$th" --import-peer "$peers/scene_500.txt" \
    --peer-state "$peers/settled_500_state.txt" --steps "$steps"
done
for th in 1 2; do
  row "2000-particle cloud, first steps" "$th" --import-peer "$peers/scene_2000.txt" --steps "$steps"
done
if [ -f "$yade_state" ]; then
  for th in 1 2; do
    printf '%-40s %s thread(s)  ' "Yade, its settled 500 bed" "$th"
    yade -j "$th" -n -f2 -x "$peers/run_yade.py" "$peers/scene_500.txt" --shape poly \
      --load "$yade_state" --warmup 0 --steps "$steps" 2>&1 | grep '^RESULT' || echo "(no RESULT line)"
  done
else
  echo "Yade: not installed here (apt-get install yade); its rows skipped"
fi
