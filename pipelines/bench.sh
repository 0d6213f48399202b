#!/usr/bin/env bash
# Through-the-pipe throughput of the geometry tools, side by side in one run, on this machine.
# Usage: pipelines/bench.sh [COUNT_PER_FACE_COUNT]   (default 1111: 9999 polyhedra)
set -euo pipefail
n=${1:-1111}
dir=${BENCH_DIR:-out/bench}
mkdir -p "$dir"
TIMEFORMAT='%R'
secs() { { time "$@" > /dev/null; } 2>&1 | tail -n 1; }
objs=$((9 * n))
echo "machine: $(nproc) cores; $objs polyhedra (faces 6..14, $n each)"
polygen --faces 6..14 --count "$n" --seed 1 > "$dir/p.obj"
abrade --levels 3 < "$dir/p.obj" > "$dir/l3.obj"
bytes=$(stat -c %s "$dir/l3.obj")
rate() { awk -v n="$1" -v s="$2" 'BEGIN { printf "%8.0f objects/s", n / s }'; }
row() { printf '%-58s %7.2f s  %s\n' "$1" "$2" "$(rate "$objs" "$2")"; }
t=$(secs polygen --faces 6..14 --count "$n" --seed 1); row "polygen" "$t"
for l in 1 2 3; do
  t=$(secs bash -c "abrade --levels $l < '$dir/p.obj'"); row "abrade --levels $l (from I_P)" "$t"
done
t=$(secs bash -c "roundness < '$dir/l3.obj'"); row "roundness of Ab_3 (from a file)" "$t"
t=$(secs bash -c "cat '$dir/l3.obj'"); printf '%-58s %7.2f s  (%d MB of Ab_3 OBJ text)\n' "cat of the same bytes (the pipe's floor)" "$t" $((bytes / 1000000))
t=$(secs bash -c "cat '$dir/l3.obj' | wc -l"); printf '%-58s %7.2f s\n' "cat | wc -l (reading every line once)" "$t"
t=$(secs bash -c "polygen --faces 6..14 --count $n --seed 1 | abrade --levels 3 | roundness"); row "polygen | abrade --levels 3 | roundness (the target: < 3 s)" "$t"
t=$(secs bash -c "polygen --faces 6..14 --count $n --seed 1 | abrade --levels 3"); row "polygen | abrade --levels 3 (writing the text)" "$t"
for th in 1 2; do
  t=$(secs env RAYON_NUM_THREADS=$th bash -c "roundness < '$dir/l3.obj'"); row "roundness of Ab_3, $th thread(s)" "$t"
done
