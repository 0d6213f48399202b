#!/usr/bin/env bash
# Runs `triax OPTIONS < SPEC` into OUT, going on from where a stopped run of the same target
# left off (a job's time limit, a reboot): its stream so far, OUT.part (and OUT.rest, what a
# resumed run had added), is cut after its last whole frame (a checkpoint in consolidation or
# a frame of loading) and the test resumes from it. OUT is then the stream of a run in one go,
# byte for byte (docs/formats/triax-stream.md). Without a whole frame it starts from SPEC.
# One run at a time writes OUT.part: a second one (the same target made or submitted again
# while the first still runs) stops at once, with a message (a lock on OUT.lock, by flock).
# Usage: pipelines/triax-resume.sh SPEC OUT [TRIAX OPTIONS...]
set -euo pipefail
spec=$1 out=$2
shift 2
part=$out.part rest=$out.rest
say() { echo "${GRANULAR_TAG:+[$GRANULAR_TAG] }triax-resume: $*" >&2; }
if command -v flock > /dev/null; then
  exec 9> "$out.lock"
  if ! flock -n 9; then
    say "$out is being made by another run (it holds $out.lock): not started twice"
    exit 1
  fi
fi
if [ -e "$rest" ]; then
  cat "$part" "$rest" > "$part.new"
  mv "$part.new" "$part"
  rm "$rest"
fi
# The line that ends the last whole frame's state: a frame record says how many records
# (lines) its state has.
last=0
if [ -s "$part" ]; then
  last=$(awk '/^\{"type":"frame"/ {
                if (match($0, /"records":[0-9]+/)) end = NR + substr($0, RSTART + 10, RLENGTH - 10)
              }
              NR == end { last = NR }
              END { print last + 0 }' "$part")
fi
if [ "$last" -gt 0 ]; then
  say "$out goes on from line $last of $part"
  head -n "$last" "$part" > "$part.new"
  mv "$part.new" "$part"
  triax "$@" < "$part" > "$rest"
  cat "$part" "$rest" > "$part.new"
  mv "$part.new" "$part"
  rm "$rest"
else
  triax "$@" < "$spec" > "$part"
fi
mv "$part" "$out"
