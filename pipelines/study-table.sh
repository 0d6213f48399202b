#!/usr/bin/env bash
# The seed study's table by group: each column's mean and standard deviation over the seeds
# (sample, n - 1; a group of one seed has its value alone), as a Markdown table on standard
# output (groups in their first order).
# Usage: pipelines/study-table.sh RUNS.csv [COLUMNS]   (rows of pipelines/study-row.sh;
#   COLUMNS: comma-separated names to show, by default every result column)
set -euo pipefail
awk -F, -v want="${2:-}" '
  # n significant digits, without an exponent for values of 100 and more.
  function num(x, n) { return (x >= 100 || x <= -100) ? sprintf("%.0f", x) : sprintf("%." n "g", x) }
  NR == 1 {
    for (i = 4; i <= NF; i++) name[i] = $i
    cols = 0
    if (want == "") { for (i = 4; i <= NF; i++) show[++cols] = i }
    else {
      n = split(want, w, ",")
      for (k = 1; k <= n; k++) {
        found = 0
        for (i = 4; i <= NF; i++) if ($i == w[k]) { show[++cols] = i; found = 1 }
        if (!found) { print "study-table: no column " w[k] > "/dev/stderr"; exit 2 }
      }
    }
    last = NF; next
  }
  { g = $1; if (!(g in n_)) order[++groups] = g; n_[g]++
    for (i = 4; i <= last; i++) { s[g, i] += $i; ss[g, i] += $i * $i } }
  END {
    printf "| group (seeds) |"; for (k = 1; k <= cols; k++) printf " %s |", name[show[k]]; print ""
    printf "|---|"; for (k = 1; k <= cols; k++) printf "---|"; print ""
    for (j = 1; j <= groups; j++) {
      g = order[j]; printf "| %s (%d) |", g, n_[g]
      for (k = 1; k <= cols; k++) {
        i = show[k]; m = s[g, i] / n_[g]
        if (n_[g] == 1) { printf " %s |", num(m, 3); continue }
        v = (ss[g, i] - n_[g] * m * m) / (n_[g] - 1); if (v < 0) v = 0
        printf " %s ± %s |", num(m, 3), num(sqrt(v), 2)
      }
      print ""
    }
  }' "$1"
