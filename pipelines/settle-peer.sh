#!/usr/bin/env bash
# Settles a peer scene (../shared/peers/yade) under our own contact law, for the engine
# benchmark. The peer's settled state carries Yade's overlaps (median 0.23 mm): with the
# paper's kn = 1e8 N/m they would blow the bed apart. So the bed is first relaxed with a soft
# kn = 5e3 N/m (about the stiffness Yade's volumetric law has at those overlaps) until the
# unbalanced-force ratio is below 1e-3, then stiffened tenfold per stage up to kn = 1e8 N/m
# (ks = kn / 2) with local damping DAMP (default 0.7), each stage until the ratio is below R or
# STEPS steps, and last relaxed with the scene's damping. A stage must outlast the time gravity
# needs to close the gaps the stiffening opens (overlaps shrink tenfold, ~0.1 mm at the bottom:
# ~5 ms, 20 000 steps at kn = 1e8); 5 000-step stages left a bed of 73 contacts.
# ABRADE=K turns every particle into its Ab_K hull first (`dem --abrade`), in place.
# Usage: pipelines/settle-peer.sh N OUT.jsonl [R [STEPS]]   (N = 500: from Yade's settled state)
# Progress and each stage's figures go to stderr; dem must be on PATH.
set -euo pipefail
n=$1 out=$2 ratio=${3:-1e-2} steps=${4:-20000} damp=${DAMP:-0.7} abrade=${ABRADE:-0}
peers=${PEERS:-../shared/peers/yade}
scene=$peers/scene_$n.txt
[ -f "$scene" ] || { echo "settle-peer: no $scene (set PEERS=DIR)" >&2; exit 1; }
start=()
[ -f "$peers/settled_${n}_state.txt" ] && start=(--peer-state "$peers/settled_${n}_state.txt")
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
echo "settle-peer: kn = 5e3 N/m" >&2
dem --import-peer "$scene" "${start[@]}" --abrade "$abrade" --kn 5e3 --ks 2.5e3 \
  --until-unbalanced 1e-3 --time 3 > "$tmp/s.jsonl"
for kn in 5e4 5e5 5e6 5e7 1e8; do
  ks=$(awk -v k="$kn" 'BEGIN { printf "%g", k / 2 }')
  echo "settle-peer: kn = $kn N/m, damping $damp" >&2
  dem --kn "$kn" --ks "$ks" --damping "$damp" --until-unbalanced "$ratio" --steps "$steps" \
    < "$tmp/s.jsonl" > "$tmp/t.jsonl"
  mv "$tmp/t.jsonl" "$tmp/s.jsonl"
done
echo "settle-peer: relaxing with the scene's damping" >&2
dem --damping 0.3 --until-unbalanced "$ratio" --steps "$steps" < "$tmp/s.jsonl" > "$tmp/t.jsonl"
mv "$tmp/t.jsonl" "$out"
