#!/usr/bin/env bash
# Settles a peer scene (../shared/peers/yade) under our own contact law, for the engine
# benchmark: the peer's settled state (or its loose lattice) is first relaxed with a soft
# kn = 5e3 N/m, about the stiffness Yade's volumetric law has at that state's overlaps, and
# then stiffened tenfold per stage up to the paper's kn = 1e8 N/m (ks = kn / 2), each stage run
# with the scene's local damping until the unbalanced-force ratio is below R, for at most
# STEPS steps (a stage only has to shrink the overlaps tenfold: a few oscillation periods).
# Usage: pipelines/settle-peer.sh N OUT.jsonl [R [STEPS]]   (N = 500: from Yade's settled state)
# Progress and each stage's figures go to stderr; dem must be on PATH.
set -euo pipefail
n=$1 out=$2 ratio=${3:-1e-2} steps=${4:-5000}
peers=${PEERS:-../shared/peers/yade}
scene=$peers/scene_$n.txt
[ -f "$scene" ] || { echo "settle-peer: no $scene (set PEERS=DIR)" >&2; exit 1; }
start=()
[ -f "$peers/settled_${n}_state.txt" ] && start=(--peer-state "$peers/settled_${n}_state.txt")
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
echo "settle-peer: stage kn = 5e3 N/m" >&2
dem --import-peer "$scene" "${start[@]}" --kn 5e3 --ks 2.5e3 \
  --until-unbalanced "$ratio" --time 3 > "$tmp/s.jsonl"
for kn in 5e4 5e5 5e6 5e7 1e8; do
  ks=$(awk -v k="$kn" 'BEGIN { printf "%g", k / 2 }')
  echo "settle-peer: stage kn = $kn N/m" >&2
  dem --kn "$kn" --ks "$ks" --until-unbalanced "$ratio" --steps "$steps" \
    < "$tmp/s.jsonl" > "$tmp/t.jsonl"
  mv "$tmp/t.jsonl" "$tmp/s.jsonl"
done
mv "$tmp/s.jsonl" "$out"
