#!/usr/bin/env bash
# The rate table: one specimen's test at several loading rates (and with the true inertia),
# each against the slowest: the largest difference of q(eps_a) and eps_v(eps_a) over the
# curve, over the slowest run's peak q (and over its largest |eps_v|), with the wall time and
# the largest inertial number. Usage: pipelines/rate-table.sh DIR SLOWEST RUN...
#   each RUN has DIR/RUN.csv (triax --csv) and DIR/RUN.err (the line /usr/bin/time wrote:
#   "NAME elapsed S s cpu ..."), e.g. pipelines/rate-table.sh out/rates r0.125 r2 r1 r0.5 r0.25
set -euo pipefail
dir=$1 slow=$2; shift 2
col() { head -n 1 "$1" | tr ',' '\n' | grep -n -x "$2" | cut -d: -f1; }
ref=$dir/$slow.csv
echo "| run | wall time (s) | largest inertial number | max |dq| / peak q | max |d eps_v| / max |eps_v| |"
echo "|---|---|---|---|---|"
for run in "$@" "$slow"; do
  csv=$dir/$run.csv
  wall=$(grep -o 'elapsed [0-9.]*' "$dir/$run.err" | cut -d' ' -f2)
  awk -F, -v n="$(col "$csv" nominal_strain)" -v q="$(col "$csv" q_boundary)" \
      -v v="$(col "$csv" volumetric_strain)" -v i="$(col "$csv" inertial)" \
      -v run="$run" -v wall="$wall" '
    FNR == 1 { next }
    NR == FNR { rq[$n] = $q; rv[$n] = $v; if ($q > peak) peak = $q;
                if ($v > vmax) vmax = $v; if (-$v > vmax) vmax = -$v; next }
    { if ($i > imax) imax = $i;
      if ($n in rq) { d = $q - rq[$n]; if (d < 0) d = -d; if (d > dq) dq = d;
                      e = $v - rv[$n]; if (e < 0) e = -e; if (e > dv) dv = e } }
    END { printf "| %s | %s | %.2e | %.1f %% | %.1f %% |\n", run, wall, imax, 100 * dq / peak, 100 * dv / vmax }
  ' "$ref" "$csv"
done
