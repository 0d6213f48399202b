#!/usr/bin/env bash
# The rate study's tables (make convergence), in markdown on standard output.
# Runs: each rate's largest inertial number (per body), its unbalanced ratio from 1 % of
# strain on, its peak q_section and the strain of it, eps_v at the end, the sliding ratio at
# 1 / 5 / 10 % of strain.
# Pairs, each rate against half of it: q_section averaged over 0.5 % of strain (windows of 5
# measurements on the 0.1 % grid), the mean and the largest difference over the slower run's
# peak q, up to 5 % of strain and past it; eps_v's largest difference over the slower run's
# range, the same; S_p's and the mean rotation's largest differences at the frames (every 0.5 %), up to 5
# % and past it. The study's criterion: q within 2 % of peak q, eps_v within 2 % of its range,
# S_p within 0.02.
# Usage: pipelines/convergence-table.sh DIR RATE... (fastest first); each RATE has
#   DIR/rRATE.triax.csv (triax --csv) and DIR/rRATE.fabric.csv (fabric on its stream).
set -euo pipefail
dir=$1 here=$(dirname "$0")
shift
col() { head -n 1 "$1" | tr ',' '\n' | grep -n -x "$2" | cut -d: -f1; }
# Every table and column first: a missing one stops with its name.
for r in "$@"; do
  for c in triax:nominal_strain triax:axial_strain triax:q_section triax:volumetric_strain \
    triax:inertial_max triax:unbalanced fabric:axial_strain fabric:sliding_ratio fabric:rotation; do
    f=$dir/r$r.${c%%:*}.csv
    [ -r "$f" ] || { echo "convergence-table: no $f" >&2; exit 1; }
    [ -n "$(col "$f" "${c#*:}")" ] || { echo "convergence-table: $f has no column ${c#*:}" >&2; exit 1; }
  done
done
echo "| rate (/s) | largest inertial number | unbalanced from 1 % | peak q_section (strain) | eps_v at the end | S_p at 1 / 5 / 10 % |"
echo "|---|---|---|---|---|---|"
for r in "$@"; do
  t=$dir/r$r.triax.csv f=$dir/r$r.fabric.csv
  sp=$(awk -F, -v e="$(col "$f" axial_strain)" -v s="$(col "$f" sliding_ratio)" '
    FNR > 1 { k = int($e * 200 + 0.5); v[k] = $s }
    END { printf "%s / %s / %s", (2 in v) ? sprintf("%.3f", v[2]) : "-",
          (10 in v) ? sprintf("%.3f", v[10]) : "-", (20 in v) ? sprintf("%.3f", v[20]) : "-" }' "$f")
  awk -F, -v r="$r" -v sp="$sp" -v e="$(col "$t" axial_strain)" -v q="$(col "$t" q_section)" \
      -v v="$(col "$t" volumetric_strain)" -v i="$(col "$t" inertial_max)" \
      -v u="$(col "$t" unbalanced)" '
    FNR == 1 { next }
    { if ($i > imax) imax = $i; if ($q > peak) { peak = $q; at = $e }
      if ($e >= 0.01) { if (umin == "" || $u < umin) umin = $u; if ($u > umax) umax = $u }
      last = $v }
    END { printf "| %s | %.1e | %s | %.0f kPa (%.1f %%) | %.2f %% | %s |\n", r, imax,
          umin == "" ? "-" : sprintf("%.3f-%.3f", umin, umax), peak / 1e3, 100 * at, 100 * last, sp }' "$t"
done
echo
echo "| rates (/s) | q: mean / largest difference to 5 % | past 5 % | eps_v: largest difference to 5 % / past | S_p: largest difference to 5 % / past | rotation: largest difference to 5 % / past | agree? |"
echo "|---|---|---|---|---|---|---|"
while [ $# -ge 2 ]; do
  fast=$1 slow=$2
  shift
  a=$dir/r$fast.triax.csv b=$dir/r$slow.triax.csv
  qv=$(awk -F, -v na="$(col "$a" nominal_strain)" -v qa="$(col "$a" q_section)" \
      -v va="$(col "$a" volumetric_strain)" -v n="$(col "$b" nominal_strain)" \
      -v q="$(col "$b" q_section)" -v v="$(col "$b" volumetric_strain)" '
    function abs(x) { return x < 0 ? -x : x }
    FNR == 1 { next }
    NR == FNR { k = int($na * 1000 + 0.5); fq[k] = $qa; fv[k] = $va; next }
    { k = int($n * 1000 + 0.5); sq[k] = $q; sv[k] = $v; if ($q > peak) peak = $q
      if (vmin == "" || $v < vmin) vmin = $v; if ($v > vmax) vmax = $v }
    END {
      for (k in sv) if (k in fv) {
        d = abs(fv[k] - sv[k]); if (k <= 50) { if (d > v1) v1 = d } else if (d > v2) v2 = d }
      for (w = 0; w < 60; w++) {
        m = 0; df = 0
        for (k = 5 * w + 1; k <= 5 * w + 5; k++) if ((k in fq) && (k in sq)) { df += fq[k] - sq[k]; m++ }
        if (m < 5) continue
        d = abs(df / m) / peak
        if (w < 10) { s1 += d; n1++; if (d > x1) x1 = d } else { s2 += d; n2++; if (d > x2) x2 = d }
      }
      range = vmax - vmin
      ok = (x1 <= 0.02) && (x2 <= 0.02) && (v1 <= 0.02 * range) && (v2 <= 0.02 * range)
      printf "%.1f %% / %.1f %% | %s | %.1f %% / %s | %d", 100 * s1 / n1, 100 * x1,
        n2 ? sprintf("%.1f %% / %.1f %%", 100 * s2 / n2, 100 * x2) : "-", 100 * v1 / range,
        n2 ? sprintf("%.1f %%", 100 * v2 / range) : "-", ok }' <("$here/on-grid.sh" "$a") <("$here/on-grid.sh" "$b"))
  fa=$dir/r$fast.fabric.csv fb=$dir/r$slow.fabric.csv
  micro=$(awk -F, -v ea="$(col "$fa" axial_strain)" -v sa="$(col "$fa" sliding_ratio)" \
      -v ra="$(col "$fa" rotation)" -v e="$(col "$fb" axial_strain)" \
      -v s="$(col "$fb" sliding_ratio)" -v r="$(col "$fb" rotation)" '
    function abs(x) { return x < 0 ? -x : x }
    FNR == 1 { next }
    NR == FNR { k = int($ea * 200 + 0.5); fs[k] = $sa; fr[k] = $ra; next }
    { k = int($e * 200 + 0.5) }
    (k in fs) && k > 0 {
      ds = abs(fs[k] - $s); dr = $r > 0 ? abs(fr[k] - $r) / $r : 0
      if (k <= 10) { if (ds > s1) s1 = ds; if (dr > r1) r1 = dr }
      else { if (ds > s2) s2 = ds; if (dr > r2) r2 = dr; past = 1 } }
    END { printf "%.3f / %s | %.0f %% / %s | %d", s1, past ? sprintf("%.3f", s2) : "-", 100 * r1,
          past ? sprintf("%.0f %%", 100 * r2) : "-", (s1 <= 0.02) && (s2 <= 0.02) }' "$fa" "$fb")
  ok=$(( ${qv##*|} && ${micro##*|} ))
  echo "| $fast / $slow | ${qv% |*} | ${micro% |*} | $([ $ok = 1 ] && echo yes || echo no) |"
done
