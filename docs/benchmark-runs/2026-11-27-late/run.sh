#!/bin/bash
# The late-night benchmark of 2026-11-27: the code at the start of the
# session (3187212, "before") and at the end ("after") alternated, three
# runs of 200 steps each with 3 people, both robots; 0 people three runs;
# 10 people one run. Needs a worktree of 3187212 at $BEFORE.
#   BEFORE=/tmp/before bash docs/benchmark-runs/2026-11-27-late/run.sh OUT
set -e
OUT=$(mkdir -p "${1:?output directory}" && cd "$1" && pwd)
AFTER=$(cd "$(dirname "$0")/../../.." && pwd)
PY=${PY:-$AFTER/.venv/bin/python}
mkdir -p "$OUT"
cd /tmp  # python -c puts the working directory first on sys.path
bench() {  # tree label args...
  local tree=$1 label=$2; shift 2
  PYTHONPATH=$tree "$PY" -c 'import sys; from sm2ith_drake.cli.main import main; sys.exit(main())' \
    bench "$@" --json "$OUT/$label.json" > "$OUT/$label.txt" 2>&1
  echo "$label: $(grep -h median "$OUT/$label.txt" | sed 's/  */ /g')"
}
loop() { "$PY" -c 'import time; t=time.perf_counter(); s=0
for i in range(3000000): s+=i
print("loop %.2f s" % (time.perf_counter()-t))'; }
loop | tee "$OUT/loop.txt"
for i in 1 2 3; do
  for side in before after; do
    tree=$AFTER; [ $side = before ] && tree=$BEFORE
    bench "$tree" "${side}_3p_$i" --robot all --humans 3 --steps 200 --profile
  done
done
for i in 1 2 3; do
  for side in before after; do
    tree=$AFTER; [ $side = before ] && tree=$BEFORE
    bench "$tree" "${side}_0p_$i" --robot all --humans 0 --steps 200
  done
done
for side in before after; do
  tree=$AFTER; [ $side = before ] && tree=$BEFORE
  bench "$tree" "${side}_10p" --robot all --humans 10 --steps 200
done
loop | tee -a "$OUT/loop.txt"
