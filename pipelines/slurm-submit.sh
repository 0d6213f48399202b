#!/usr/bin/env bash
# Submits `make paper` to a Slurm cluster: one job per run (its specimen and its triaxial test,
# `make out/paper/G-S.triax.jsonl`), then one job that draws the figures (`make paper`) once
# every run's job has ended well (--dependency=afterok; if one fails, the figures' job waits
# and Slurm reports its dependency as never satisfied). Before submitting, and only then, it
# builds the tools (cargo, on this machine) and makes the groups' templates (seconds); no
# simulation runs outside a job. A run's job is named granular-G-S with
# --dependency=singleton, so a run submitted again while its job still runs waits for it (and
# the test's lock stops a second writer anyway); a run stopped by its time limit goes on from
# its last whole frame when submitted again. Each job's log: OUT/slurm/NAME-JOBID.out.
#
# Usage: pipelines/slurm-submit.sh [--dry-run] [--time T] [--cpus N] [VAR=VALUE ...] [-- SBATCH...]
#   --dry-run   print the commands it would run and the sbatch lines it would submit, run none
#   --time T    each run's time limit (default 2:00:00: 10-15 min of pack and 25-65 min of triax
#               at the paper's scale on 2 cores); the figures' job gets 0:30:00
#   --cpus N    CPUs per job (default 2); the tools take their threads from it
#   VAR=VALUE   make variables for every make, e.g. PAPER_SEEDS=1 PAPER_GROUPS="ip ab3" SCALE=smoke
#   -- ...      further sbatch options for every job (--partition=P, --account=A, --mem=4G)
set -euo pipefail
cd "$(dirname "$0")/.."
dry=0 time=2:00:00 cpus=2 vars=() extra=()
while [ $# -gt 0 ]; do
  case $1 in
    --dry-run) dry=1 ;;
    --time) time=${2:?--time needs a value}; shift ;;
    --cpus) cpus=${2:?--cpus needs a value}; shift ;;
    --) shift; extra=("$@"); break ;;
    [A-Z]*=*) vars+=("$1") ;;
    -h|--help) sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;;
    *) echo "slurm-submit: '$1' is not an option (see --help)" >&2; exit 2 ;;
  esac
  shift
done
[[ $cpus =~ ^[1-9][0-9]*$ ]] || { echo "slurm-submit: --cpus must be a whole number, got '$cpus'" >&2; exit 2; }
exec 3>&1  # the sbatch lines of a dry run, from inside $(submit ...)
# The make command of every job, its variables quoted for the job's shell.
quoted=""
for v in "${vars[@]}"; do quoted+=" $(printf '%q' "$v")"; done
show() {  # a command as a shell reads it: words with other than [A-Za-z0-9_=:,./%+@-] quoted
  local w out=()
  for w in "$@"; do
    if [[ $w =~ ^[A-Za-z0-9_=:,./%+@-]+$ ]]; then out+=("$w"); else out+=("'${w//\'/\'\\\'\'}'"); fi
  done
  echo "${out[*]}"
}
run() {  # a command on this machine (printed only, with --dry-run)
  echo "+ $(show "$@")" >&2
  [ "$dry" = 1 ] || "$@"
}
submit() {  # NAME sbatch options... : prints the job's id (a placeholder with --dry-run)
  local name=$1; shift
  local cmd=(sbatch --parsable --job-name="$name" "$@")
  if [ "$dry" = 1 ]; then
    show "${cmd[@]}" >&3
    echo "JOB_$name"
  else
    "${cmd[@]}"
  fi
}
command -v sbatch > /dev/null || [ "$dry" = 1 ] || { echo "slurm-submit: no sbatch on PATH (is this a Slurm login node?)" >&2; exit 1; }
{ read -r paper; read -r -a runs; } < <(make -s --no-print-directory "${vars[@]}" paper-list)
[ "${#runs[@]}" -gt 0 ] || { echo "slurm-submit: no runs (PAPER_GROUPS, PAPER_SEEDS?)" >&2; exit 2; }
run make --no-print-directory "${vars[@]}" build paper-templates
logs=$paper/slurm
[ "$dry" = 1 ] || mkdir -p "$logs"
threads='RAYON_NUM_THREADS=$SLURM_CPUS_PER_TASK'
ids=()
for r in "${runs[@]}"; do
  ids+=("$(submit "granular-$r" --dependency=singleton --time="$time" --cpus-per-task="$cpus" \
    --output="$logs/%x-%j.out" "${extra[@]}" \
    --wrap="$threads make --no-print-directory$quoted $paper/$r.triax.jsonl")")
done
deps=$(IFS=:; echo "${ids[*]}")
submit granular-paper-figures --dependency="afterok:$deps" --time=0:30:00 --cpus-per-task="$cpus" \
  --output="$logs/%x-%j.out" "${extra[@]}" --wrap="$threads make --no-print-directory$quoted paper" > /dev/null
if [ "$dry" = 1 ]; then
  echo "slurm-submit: dry run: ${#runs[@]} runs and the figures' job would be submitted" >&2
else
  echo "slurm-submit: ${#runs[@]} runs and the figures' job submitted; logs in $logs (squeue --me)" >&2
fi
