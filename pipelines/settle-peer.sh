#!/usr/bin/env bash
# Settles the Yade comparison's scenes (pipelines/yade/scenes.sh puts them in out/bench/peers) under our own contact law, for the
# engine benchmark (pipelines/bench-dem.sh). Each step a mode:
#
#   settle-peer.sh soft N OUT.jsonl
#       The N-particle scene (500: from Yade's settled state; 2000, 5000: from the falling
#       cloud) settled with a soft kn = 5e3 N/m (about the stiffness of Yade's volumetric law at
#       its overlaps) at 0.5 x the critical time step, until the unbalanced-force ratio is below
#       1e-3: a dense bed at rest, 5-6 contacts per particle as the peer counts them.
#   settle-peer.sh nine N OUT.jsonl
#       The benchmark scene: the N-particle scene's falling cloud with every particle
#       replaced by one of the nine templates (`polygen --faces 6..14 --seed 7`, the paper's)
#       at its size, centroid and principal axes (`dem --templates`), settled as with soft.
#       The bodies share nine shapes, as a specimen of the paper's does.
#   settle-peer.sh abrade K IN.jsonl OUT.jsonl
#       Every particle of a settled bed turned into its Ab_K hull in place (`dem --abrade K`),
#       then settled again the same way for at most 0.5 s (the abraded particles are smaller:
#       the bed loosens and sinks).
#   settle-peer.sh cut V IN.jsonl OUT.jsonl
#       Every hull of a settled bed cut to V vertices in place (`dem --simplify V`, inside the
#       full hulls, so contacts open), the ids renumbered along space, then settled again at
#       the bed's own stiffness for at most 0.3 s, until the ratio is below 1e-2: about as many
#       contacts per particle as the full hulls' bed.
#   settle-peer.sh stiffen IN.jsonl OUT.jsonl [R [STEPS]]
#       A soft bed stiffened tenfold per stage up to the paper's kn = 1e8 N/m (ks = kn / 2),
#       local damping DAMP (default 0.7), each stage until the ratio is below R (1e-2) or STEPS
#       (20 000) steps, then relaxed with the scene's damping 0.3 the same way. A stiffening
#       shrinks the overlaps tenfold and opens gaps that gravity closes in ~5 ms (20 000 steps
#       at kn = 1e8); even so the bed is still compacting at the end (0.3 ratio, docs/performance.md):
#       settling at the paper's stiffness takes simulated time that costs hours.
#
# Progress and each stage's figures go to stderr; dem (and polygen for nine) must be on PATH.
set -euo pipefail
usage() { sed -n 's/^#   settle-peer.sh/usage: settle-peer.sh/p' "$0" >&2; exit 2; }
mode=${1:-}
[ $# -ge 1 ] && shift
peers=${PEERS:-out/bench/peers}
soft=(--kn 5e3 --ks 2.5e3 --safety 0.5 --until-unbalanced 1e-3)
case $mode in
  soft | nine)
    [ $# -eq 2 ] || usage
    n=$1 out=$2
    scene=$peers/scene_$n.txt
    [ -f "$scene" ] || { echo "settle-peer: no $scene (set PEERS=DIR)" >&2; exit 1; }
    start=()
    if [ "$mode" = nine ]; then
      polygen --faces 6..14 --seed 7 > "$out.templates.obj"
      start=(--templates "$out.templates.obj")
      echo "settle-peer: $n particles as the nine templates at kn = 5e3 N/m" >&2
    else
      [ -f "$peers/settled_${n}_state.txt" ] && start=(--peer-state "$peers/settled_${n}_state.txt")
      echo "settle-peer: $n particles at kn = 5e3 N/m" >&2
    fi
    dem --import-peer "$scene" "${start[@]}" "${soft[@]}" --time 4 > "$out.tmp"
    rm -f "$out.templates.obj"
    ;;
  abrade)
    [ $# -eq 3 ] || usage
    levels=$1 in=$2 out=$3
    echo "settle-peer: $in as Ab_$levels hulls, settling again at kn = 5e3 N/m" >&2
    dem --abrade "$levels" "${soft[@]}" --time 0.5 < "$in" > "$out.tmp"
    ;;
  cut)
    [ $# -eq 3 ] || usage
    vertices=$1 in=$2 out=$3
    echo "settle-peer: $in cut to $vertices vertices a hull, settling again" >&2
    dem --renumber --simplify "$vertices" --time 0.3 --until-unbalanced 1e-2 < "$in" > "$out.tmp"
    ;;
  stiffen)
    [ $# -ge 2 ] && [ $# -le 4 ] || usage
    in=$1 out=$2 ratio=${3:-1e-2} steps=${4:-20000} damp=${DAMP:-0.7}
    cp "$in" "$out.tmp"
    for kn in 5e4 5e5 5e6 5e7 1e8; do
      ks=$(awk -v k="$kn" 'BEGIN { printf "%g", k / 2 }')
      echo "settle-peer: kn = $kn N/m, damping $damp" >&2
      dem --kn "$kn" --ks "$ks" --damping "$damp" --until-unbalanced "$ratio" --steps "$steps" \
        < "$out.tmp" > "$out.next"
      mv "$out.next" "$out.tmp"
    done
    echo "settle-peer: relaxing with the scene's damping" >&2
    dem --damping 0.3 --until-unbalanced "$ratio" --steps "$steps" < "$out.tmp" > "$out.next"
    mv "$out.next" "$out.tmp"
    ;;
  *) usage ;;
esac
mv "$out.tmp" "$out"
