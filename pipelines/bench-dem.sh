#!/usr/bin/env bash
# DEM engine throughput, side by side in one run, with 1 and 2 threads, on the peer benchmark's
# scenes (pipelines/yade/scenes.sh puts them in out/bench/peers), each bed made once by pipelines/settle-peer.sh and kept in
# out/bench/ (the first run takes about two hours; the beds' logs are kept beside them):
# - the benchmark's scenes proper: the same clouds with every particle one of the nine templates
#   (`dem --templates`, shared shapes as in a specimen), settled the same way, and as Ab_3;
# - dense beds at rest, 5-6 contacts per particle (the benchmark): 500 (from Yade's
#   settled state), 2000 and 5000 particles (from the falling clouds), settled with a soft
#   kn = 5e3 N/m, and the same beds as Ab_3 hulls (`dem --abrade 3`, settled again). A step's
#   cost depends on the contacts, not on kn: timed at the kn they settled with.
#   BIG=0 skips the 2000 and 5000 beds, AB3=0 the Ab_3 beds, AB3_SIZES="500 2000" the Ab_3
#   bed of 5000 (settling it again after abrading takes about an hour);
# - the 500 Ab_3 bed with its hulls cut to 200, 100, 50 vertices (`dem --simplify`), and the
#   2000 Ab_3 bed of the nine templates cut alike and settled again;
# - the 500 bed stiffened to the paper's kn = 1e8 N/m (fewer, thinner contacts), and as Ab_3;
# - Yade's own settled state loaded as it is (its volumetric law leaves overlaps of 0.23 mm:
#   deep contacts under our law, so this measures deep-overlap cost);
# - the 2000-particle scene's first steps (a loose cloud: broad phase and wall checks);
# - Yade itself on its own settled 500 bed, when `yade` is installed (settled once, 16-25 minutes).
# Each of our rows also prints where the step time goes and the peak resident memory, and the
# contacts per particle as the peer counts them. Results: docs/performance.md.
# Usage: pipelines/bench-dem.sh [STEPS]   (default 1000; Yade: YADE_STEPS, default 200, its
# 1.4e3 particle-steps/s make 1000 steps six minutes; dem must be on PATH)
set -euo pipefail
steps=${1:-1000} ysteps=${YADE_STEPS:-200}
peers=${PEERS:-${OUT:-out}/bench/peers}
[ -n "${PEERS:-}" ] || "$(dirname "$0")/yade/scenes.sh" "$peers"
out=${OUT:-out}/bench
settle=$(dirname "$0")/settle-peer.sh
if [ ! -f "$peers/scene_500.txt" ]; then
  echo "bench-dem: no peer scenes in $peers (set PEERS=DIR); skipped"
  exit 0
fi
mkdir -p "$out"
make_bed() {  # bed file, what it is, settle-peer.sh arguments...
  local bed=$1 what=$2; shift 2
  if [ ! -f "$bed" ]; then
    echo "bench-dem: making $bed ($what; once)"
    PEERS=$peers "$settle" "$@" 2>"${bed%.jsonl}.log"
  fi
}
sizes=(500)
[ "${BIG:-1}" = 1 ] && sizes+=(2000 5000)
for n in "${sizes[@]}"; do
  make_bed "$out/soft$n.jsonl" "$n particles settled at kn = 5e3" soft "$n" "$out/soft$n.jsonl"
  if [ "${AB3:-1}" = 1 ] && [[ " ${AB3_SIZES:-500 2000 5000} " == *" $n "* ]]; then
    make_bed "$out/ab3soft$n.jsonl" "the same as Ab_3 hulls" abrade 3 "$out/soft$n.jsonl" \
      "$out/ab3soft$n.jsonl"
  fi
done
# The benchmark's scenes proper: the nine templates, shared (`dem --templates`), in the peer's
# boxes; NINE_SIZES picks the sizes (default 500 2000 5000), their Ab_3 beds unless AB3=0.
nine=(${NINE_SIZES:-500 2000 5000})
for n in "${nine[@]}"; do
  make_bed "$out/nine$n.jsonl" "$n particles of the nine templates at kn = 5e3" nine "$n" \
    "$out/nine$n.jsonl"
  if [ "${AB3:-1}" = 1 ]; then
    make_bed "$out/ab3nine$n.jsonl" "the same as Ab_3 hulls" abrade 3 "$out/nine$n.jsonl" \
      "$out/ab3nine$n.jsonl"
  fi
done
make_bed "$out/stiff500.jsonl" "the 500 bed at kn = 1e8" stiffen "$out/soft500.jsonl" \
  "$out/stiff500.jsonl"
if [ "${AB3:-1}" = 1 ]; then
  make_bed "$out/ab3stiff500.jsonl" "its Ab_3 bed at kn = 1e8" stiffen "$out/ab3soft500.jsonl" \
    "$out/ab3stiff500.jsonl"
fi
if [ -f "$out/nine500.jsonl" ]; then
  make_bed "$out/stiffnine500.jsonl" "the nine-template 500 bed at kn = 1e8" stiffen \
    "$out/nine500.jsonl" "$out/stiffnine500.jsonl"
fi
# Yade on the same machine in the same run, when it is installed: its own settled 500 bed
# (the peer README's recipe, about 16-25 minutes once), then the same timed steps from it.
# The recipe stops at 840 s of wall time, which reached t = 0.65 s (13 000 steps, 5.5 contacts
# a particle) on the peer's machine but only t = 0.45 s (3.1 contacts a particle) on a slower
# or busier one: the bed, and with it Yade's cost per step, would depend on the
# hour. So the settling ends at the peer's 13 000 steps instead, whatever they take.
yade_state=$out/yade-settled500.xml.bz2
if command -v yade >/dev/null && [ ! -f "$yade_state" ]; then
  echo "bench-dem: settling the 500 scene in Yade into $yade_state (once, 16-25 min)"
  yade -j 2 -n -f2 -x "$peers/run_yade.py" "$peers/scene_500.txt" --shape poly --warmup 0 \
    --settle 0.64 --save "$yade_state" --steps 10 >"$out/yade-settle.log" 2>&1
fi
echo "machine: $(nproc) cores; dem, $steps timed steps each; Yade, $ysteps"
row() {  # label, threads, dem arguments... (the scene on stdin)
  local label=$1 th=$2; shift 2
  local log
  log=$(RAYON_NUM_THREADS=$th dem "$@" 2>&1 >/dev/null)
  printf '%-40s %s thread(s)  %s\n' "$label" "$th" "$(grep 'particle-steps/s' <<<"$log")"
  grep -E 'step time|peak resident' <<<"$log" | sed 's/^/      /'
}
for n in "${sizes[@]}"; do
  for th in 1 2; do
    row "$n bed at rest, kn = 5e3 (ours)" "$th" --steps "$steps" < "$out/soft$n.jsonl"
  done
  if [ -f "$out/ab3soft$n.jsonl" ]; then
    for th in 1 2; do
      row "$n bed of Ab_3 hulls, kn = 5e3 (ours)" "$th" --steps "$steps" < "$out/ab3soft$n.jsonl"
    done
  fi
done
# Each as the beds' ids come (the peer's order: at random in space) and renumbered along a
# space-filling curve (`dem --renumber`, done before the timed steps).
for n in "${nine[@]}"; do
  for bed in "nine$n:$n bed of the nine templates (ours)" "ab3nine$n:$n bed of their Ab_3 hulls (ours)"; do
    [ -f "$out/${bed%%:*}.jsonl" ] || continue
    for th in 1 2; do
      row "${bed#*:}" "$th" --steps "$steps" < "$out/${bed%%:*}.jsonl"
    done
    for th in 1 2; do
      row "${bed#*:}, ids along space" "$th" --renumber --steps "$steps" < "$out/${bed%%:*}.jsonl"
    done
  done
done
# Speed against shape error: the 500 Ab_3 bed with its hulls cut to a vertex budget in place
# (`dem --simplify N`: inside the full hulls, so a few contacts open; not settled again).
if [ -f "$out/ab3soft500.jsonl" ]; then
  for budget in 200 100 50; do
    for th in 1 2; do
      row "500 Ab_3 bed cut to $budget vertices" "$th" --simplify "$budget" --steps "$steps" \
        < "$out/ab3soft500.jsonl"
    done
  done
fi
# The same on the benchmark's bed at equal contacts: the 2000 Ab_3 bed of the nine templates, its
# hulls cut to a vertex budget and settled again (`settle-peer.sh cut`; about 30 s each, once),
# so each keeps about 5 contacts per particle instead of losing those the cut opens.
if [ -f "$out/ab3nine2000.jsonl" ]; then
  for budget in 200 100 50; do
    cut=$out/ab3nine2000-v$budget.jsonl
    make_bed "$cut" "cut to $budget vertices and settled again" cut "$budget" \
      "$out/ab3nine2000.jsonl" "$cut"
    for th in 1 2; do
      row "2000 Ab_3 bed cut to $budget vertices, settled" "$th" --steps "$steps" < "$cut"
    done
  done
fi
for bed in "stiff500:500 bed at kn = 1e8 (ours)" "ab3stiff500:500 Ab_3 bed at kn = 1e8 (ours)" \
  "stiffnine500:500 nine-template bed at kn = 1e8"; do
  [ -f "$out/${bed%%:*}.jsonl" ] || continue
  for th in 1 2; do
    row "${bed#*:}" "$th" --steps "$steps" < "$out/${bed%%:*}.jsonl"
  done
done
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
      --load "$yade_state" --warmup 0 --steps "$ysteps" 2>&1 | grep '^RESULT' || echo "(no RESULT line)"
  done
else
  echo "Yade: not installed here (apt-get install yade); its rows skipped"
fi
