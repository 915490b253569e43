#!/bin/bash
# Alternate live_plan.py runs of two checkouts with the tracer loaded (session 22, helper C).
# Usage: OLD=/path/old NEW=/path/new OUT=/tmp/out ab.sh PAIRS TAG
# (OLD: e.g. `git archive <base> services schemas docs tests bench | tar -x -C $OLD`)
HERE=$(cd "$(dirname "$0")" && pwd)
for i in $(seq 1 "$1"); do
  for v in old new; do
    if [ $v = old ]; then R=$OLD; else R=$NEW; fi
    f=$OUT/$2-$v-$i
    rm -f "$f.jsonl"
    echo "$(date -u +%T) $v $i load: $(cut -d' ' -f1-3 /proc/loadavg)" >> "$OUT/$2.log"
    (cd "$R" && AUTOCHAIR_PLAN_TRACE=$f.jsonl PYTHONPATH=$HERE:$R/services:$R/schemas:$R \
      timeout 600 python docs/experiments/scripts/live_plan.py) > "$f.out" 2>&1
    echo "$(date -u +%T) done $v $i load: $(cut -d' ' -f1-3 /proc/loadavg)" >> "$OUT/$2.log"
  done
done
