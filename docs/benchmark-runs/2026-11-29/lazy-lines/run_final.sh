#!/bin/bash
# The shipped controller of the fourteenth session's end (far robot lines
# and the budget of 100 by default), alternated with the budget off:
#   bash docs/benchmark-runs/2026-11-29/lazy-lines/run_final.sh OUT
set -e
out=${1:?usage: run_final.sh OUT}
mkdir -p "$out"
loop() { python3 -c "import time;t=time.time();s=0
for i in range(3000000): s+=i
print(f'loop {time.time()-t:.2f} s')"; }
loop | tee "$out/loop_before.txt"
for round in 1 2 3; do
  for b in 100 0; do
    sm2ith bench --robot all --humans 10 --steps 200 \
      --scenario_text "{controller: {qp_iteration_budget: $b}}" \
      --json "$out/10p_budget${b}_run${round}.json" | tee "$out/10p_budget${b}_run${round}.txt"
  done
done
for h in 3 0; do
  sm2ith bench --robot all --humans $h --steps 200 \
    --json "$out/${h}p.json" | tee "$out/${h}p.txt"
done
loop | tee "$out/loop_after.txt"
