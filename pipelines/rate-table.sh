#!/usr/bin/env bash
# The rate table: one specimen's test at several loading rates (and with the true inertia),
# each against the slowest: the largest difference of q(eps_a) and eps_v(eps_a) over the
# curve, over the slowest run's peak q (and over its largest |eps_v|); the same for the curves
# averaged over 1 % of axial strain (11 measurements), which leaves out the stick-slip drops
# that come at different strains in each run; the same again up to 5 % of axial strain (before
# the runs' stick-slip histories part); the wall time and the largest inertial number.
# Usage: pipelines/rate-table.sh DIR SLOWEST RUN...
#   each RUN has DIR/RUN.csv (triax --csv, measurements every 0.1 %) and DIR/RUN.err (with the
#   line /usr/bin/time wrote: "NAME elapsed S s cpu ..."),
#   e.g. pipelines/rate-table.sh out/rates r0.125 r2 r1 r0.5 r0.25
set -euo pipefail
dir=$1 slow=$2; shift 2
col() { head -n 1 "$1" | tr ',' '\n' | grep -n -x "$2" | cut -d: -f1; }
ref=$dir/$slow.csv
echo "| run | wall time (s) | largest inertial number | max dq / peak q | max d eps_v / max eps_v | the same averaged over 1 % | averaged, to 5 % |"
echo "|---|---|---|---|---|---|---|"
for run in "$@" "$slow"; do
  csv=$dir/$run.csv
  wall=$(grep -o 'elapsed [0-9.]*' "$dir/$run.err" | cut -d' ' -f2)
  awk -F, -v n="$(col "$csv" nominal_strain)" -v q="$(col "$csv" q_boundary)" \
      -v v="$(col "$csv" volumetric_strain)" -v i="$(col "$csv" inertial)" \
      -v run="$run" -v wall="$wall" '
    function abs(x) { return x < 0 ? -x : x }
    FNR == 1 { next }
    NR == FNR { k = int($n * 1000 + 0.5); rq[k] = $q; rv[k] = $v;
                if ($q > peak) peak = $q; if (abs($v) > vmax) vmax = abs($v); next }
    { k = int($n * 1000 + 0.5); tq[k] = $q; tv[k] = $v; if ($i > imax) imax = $i;
      if (k > kmax) kmax = k }
    END {
      for (k = 0; k <= kmax; k++) {
        if (!(k in tq) || !(k in rq)) continue;
        dq = abs(tq[k] - rq[k]); dv = abs(tv[k] - rv[k]);
        if (dq > mq) mq = dq; if (dv > mv) mv = dv;
        sq = sr = sv = srv = m = 0;
        for (j = k - 5; j <= k + 5; j++) if ((j in tq) && (j in rq)) {
          sq += tq[j]; sr += rq[j]; sv += tv[j]; srv += rv[j]; m++ }
        if (m == 11) { a = abs(sq - sr) / m; b = abs(sv - srv) / m;
                       if (a > aq) aq = a; if (b > av) av = b
                       if (k <= 50) { if (a > eq) eq = a; if (b > ev) ev = b } }
      }
      printf "| %s | %s | %.2e | %.1f %% | %.1f %% | %.1f %%, %.1f %% | %.1f %%, %.1f %% |\n",
        run, wall, imax, 100 * mq / peak, 100 * mv / vmax, 100 * aq / peak, 100 * av / vmax,
        100 * eq / peak, 100 * ev / vmax
    }
  ' <(pipelines/on-grid.sh "$ref") <(pipelines/on-grid.sh "$csv")
done
