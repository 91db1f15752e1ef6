#!/bin/bash
# Issue 13, 10 people: lazy DT-CBF rows (controller.lazy_barrier_distance)
# against every row, alternated, 200 steps each, both robots.
#   bash docs/benchmark-runs/2026-11-29/lazy-rows/run.sh OUT
set -e
OUT=${1:-docs/benchmark-runs/2026-11-29/lazy-rows}
loop() { python -c "import time; t=time.perf_counter(); s=0
for i in range(3000000): s+=i
print(f'loop {time.perf_counter()-t:.2f} s')" >> "$OUT/loop.txt"; }
loop
for run in 1 2 3; do
  for d in 0 0.5; do
    sm2ith bench --robot all --humans 10 --steps 200 \
      --scenario_text "{controller: {lazy_barrier_distance: $d}}" \
      --json "$OUT/10p_lazy${d}_run$run.json" > "$OUT/10p_lazy${d}_run$run.txt" 2>&1
  done
done
for d in 0 0.5; do
  sm2ith bench --robot all --humans 10 --steps 200 --rti_iterations 1 \
    --scenario_text "{controller: {lazy_barrier_distance: $d}}" \
    --json "$OUT/10p_1pass_lazy$d.json" > "$OUT/10p_1pass_lazy$d.txt" 2>&1
done
sm2ith bench --robot all --humans 5 --steps 200 \
  --scenario_text "{controller: {lazy_barrier_distance: 0.5}}" \
  --json "$OUT/5p_lazy0.5.json" > "$OUT/5p_lazy0.5.txt" 2>&1
sm2ith bench --robot all --humans 5 --steps 200 \
  --json "$OUT/5p_lazy0.json" > "$OUT/5p_lazy0.txt" 2>&1
loop
