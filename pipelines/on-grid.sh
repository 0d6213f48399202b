#!/usr/bin/env bash
# A triax measurement table (triax --csv) with only the rows measured on the 0.1 % grid of
# axial strain (nominal_strain a whole multiple of 0.001): the header, then those rows, not
# the opening's finer measurements before the first 0.1 %, which runs made before the opening
# was the default lack. Usage: pipelines/on-grid.sh TABLE.csv
set -euo pipefail
n=$(head -n 1 "$1" | tr ',' '\n' | grep -n -x nominal_strain | cut -d: -f1)
awk -F, -v n="$n" '
  function abs(x) { return x < 0 ? -x : x }
  FNR == 1 || abs($n * 1000 - int($n * 1000 + 0.5)) <= 1e-6' "$1"
