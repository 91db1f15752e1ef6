#!/bin/bash
# 2026-11-29, twelfth session: safety.turn_monitoring on and off, alternated,
# the same hour (measured at 89b0a40's parent, b51824d, where it was off by
# default; both settings are given explicitly).
#   bash docs/benchmark-runs/2026-11-29/twelfth/run.sh OUT
set -e
OUT=$(mkdir -p "${1:?output directory}" && cd "$1" && pwd)
python -c "import time; t=time.perf_counter(); s=0
for i in range(3000000): s+=i
print(f'loop {time.perf_counter()-t:.2f} s')" >> "$OUT/loop.txt"
for r in 1 2; do
  for b in false true; do
    name=$([ $b = true ] && echo on || echo off)
    sm2ith bench --robot all --humans 3 --steps 200 --json "$OUT/${name}_3p_$r.json" \
      --scenario_text "{safety: {turn_monitoring: $b}}" > "$OUT/${name}_3p_$r.txt" 2>&1
  done
done
for b in false true; do
  name=$([ $b = true ] && echo on || echo off)
  sm2ith bench --robot all --humans 10 --steps 200 --json "$OUT/${name}_10p.json" \
    --scenario_text "{safety: {turn_monitoring: $b}}" > "$OUT/${name}_10p.txt" 2>&1
done
# Then, on 89b0a40 (the monitoring on by default): a third 3-person run and
# one with 0 people.
sm2ith bench --robot all --humans 3 --steps 200 --json "$OUT/default_3p_3.json" > "$OUT/default_3p_3.txt" 2>&1
sm2ith bench --robot all --humans 0 --steps 200 --json "$OUT/default_0p.json" > "$OUT/default_0p.txt" 2>&1
# After the review (one rollout in the warm start where the unbounded one
# keeps within the turn bounds): the same QP iterations.
sm2ith bench --robot all --humans 3 --steps 200 --json "$OUT/review_3p.json" > "$OUT/review_3p.txt" 2>&1
sm2ith bench --robot all --humans 10 --steps 200 --json "$OUT/review_10p.json" > "$OUT/review_10p.txt" 2>&1
