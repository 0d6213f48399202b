#!/usr/bin/env bash
# fabric's throughput and memory on a triax stream (default: the paper-scale
# out/paper/ip-1.triax.jsonl, else the quick out/triax-ip.jsonl), against the engine's own
# state reader on the same bytes (`dem --frame last --steps 0`, which parses every state),
# alternating, ROUNDS times (default 3). The target: fabric within 2x of the reader.
# Usage: pipelines/bench-fabric.sh [STREAM [ROUNDS]]   (fabric and dem on PATH)
set -euo pipefail
stream=${1:-out/paper/ip-1.triax.jsonl}
[ -f "$stream" ] || stream=out/triax-ip.jsonl
[ -f "$stream" ] || { echo "bench-fabric: no triax stream (make fig9 or make paper); skipped"; exit 0; }
rounds=${2:-3}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
bytes=$(stat -c %s "$stream")
states=$(grep -c '"type":"header"' "$stream")
for ((k = 1; k <= rounds; k++)); do
  /usr/bin/time -f "%e %M" -o "$tmp/reader" dem --frame last --steps 0 < "$stream" > /dev/null
  /usr/bin/time -f "%e %M" -o "$tmp/fabric" fabric --quiet < "$stream" > /dev/null
  read -r tr mr < "$tmp/reader"
  read -r tf mf < "$tmp/fabric"
  awk -v tr="$tr" -v tf="$tf" -v mr="$mr" -v mf="$mf" -v b="$bytes" -v n="$states" -v k="$k" \
      -v s="$stream" 'BEGIN {
    printf "bench-fabric %s (%.0f MB, %d states) round %d: reader %.2f s (%.0f MB/s, %.0f MB max RSS), fabric %.2f s (%.0f MB/s, %.0f MB max RSS): fabric/reader %.2f\n",
      s, b / 1e6, n, k, tr, b / 1e6 / tr, mr / 1e3, tf, b / 1e6 / tf, mf / 1e3, tf / tr }'
done
