#!/usr/bin/env bash
# One row of the seed study's table: a test's macro results (from triax --summary) and its
# micro results (from fabric's table of its frames): coordination (with and without rattlers)
# at the start of loading and at the end, the largest sliding ratio, the mean rotation at the
# end, the anisotropies and the three stress ratios at the frame of peak q.
# Usage: pipelines/study-row.sh GROUP SEED LEVEL SUMMARY.json FABRIC.csv, or --header
set -euo pipefail
if [ "${1:-}" = --header ]; then
  echo "group,seed,level,peak_q_kpa,peak_strain,e50_mpa,poisson,friction_angle,dilatancy_angle,final_volumetric_strain,z_start,z_end,zm_start,zm_end,sliding_peak,rotation_end,a_c_peak,a_bn_peak,a_fn_peak,a_ft_peak,ratio19_peak,ratio9_peak,ratio20_peak"
  exit 0
fi
group=$1 seed=$2 level=$3 summary=$4 fabric=$5
field() { sed -E "s/.*\"$1\":(-?[0-9.eE+-]+).*/\1/" "$summary"; }
macro=$(awk -v q="$(field peak_q)" -v e="$(field peak_strain)" -v m="$(field e50)" \
  -v nu="$(field poisson_ratio)" -v phi="$(field friction_angle)" -v psi="$(field dilatancy_angle)" \
  -v ev="$(field final_volumetric_strain)" \
  'BEGIN { printf "%.1f,%.4f,%.2f,%.3f,%.2f,%.2f,%.4f", q / 1e3, e, m / 1e6, nu, phi, psi, ev }')
micro=$(awk -F, '
  NR == 1 { for (i = 1; i <= NF; i++) c[$i] = i; next }
  { last = $0; n++
    if (n == 1) { z0 = $c["coordination"]; zm0 = $c["mechanical_coordination"] }
    if ($c["sliding_ratio"] > sp) sp = $c["sliding_ratio"]
    if (n == 1 || $c["q_boundary"] > qmax) { qmax = $c["q_boundary"]; peak = $0 } }
  END {
    split(last, l, ","); split(peak, p, ",")
    printf "%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f",
      z0, l[c["coordination"]], zm0, l[c["mechanical_coordination"]], sp, l[c["rotation"]],
      p[c["a_c"]], p[c["a_bn"]], p[c["a_fn"]], p[c["a_ft"]],
      p[c["ratio_anisotropy"]], p[c["ratio_contacts"]], p[c["ratio_boundary"]] }' "$fabric")
echo "$group,$seed,$level,$macro,$micro"
