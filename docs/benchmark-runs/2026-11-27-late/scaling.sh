#!/bin/bash
# The scaling table of the late-night benchmark: 0–20 people, both robots
# (100 steps up to 10 people, 30 steps for 15 and 20).
#   bash docs/benchmark-runs/2026-11-27-late/scaling.sh OUT
set -e
OUT=$(mkdir -p "${1:?output directory}" && cd "$1" && pwd)
ROOT=$(cd "$(dirname "$0")/../../.." && pwd)
PY=${PY:-$ROOT/.venv/bin/python}
mkdir -p "$OUT"
cd /tmp
for h in 0 1 2 3 5 10 15 20; do
  steps=100; [ $h -gt 10 ] && steps=30
  PYTHONPATH=$ROOT "$PY" -c 'import sys; from sm2ith_drake.cli.main import main; sys.exit(main())' \
    bench --robot all --humans $h --steps $steps --json "$OUT/scaling_${h}p.json" > "$OUT/scaling_${h}p.txt" 2>&1
  echo "$h: $(grep -h median "$OUT/scaling_${h}p.txt" | sed 's/  */ /g' | tr '\n' ' ')"
done
