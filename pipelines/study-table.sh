#!/usr/bin/env bash
# The seed study's table by group: each column's mean and standard deviation over the seeds
# (sample, n - 1), as a Markdown table on standard output (groups in their first order).
# Usage: pipelines/study-table.sh RUNS.csv   (rows of pipelines/study-row.sh)
set -euo pipefail
awk -F, '
  NR == 1 { for (i = 4; i <= NF; i++) name[i] = $i; cols = NF; next }
  { g = $1; if (!(g in n)) order[++groups] = g; n[g]++
    for (i = 4; i <= cols; i++) { s[g, i] += $i; ss[g, i] += $i * $i } }
  END {
    printf "| group (seeds) |"; for (i = 4; i <= cols; i++) printf " %s |", name[i]; print ""
    printf "|---|"; for (i = 4; i <= cols; i++) printf "---|"; print ""
    for (k = 1; k <= groups; k++) {
      g = order[k]; printf "| %s (%d) |", g, n[g]
      for (i = 4; i <= cols; i++) {
        m = s[g, i] / n[g]
        v = n[g] > 1 ? (ss[g, i] - n[g] * m * m) / (n[g] - 1) : 0; if (v < 0) v = 0
        printf " %.3g ± %.2g |", m, sqrt(v)
      }
      print ""
    }
  }' "$1"
