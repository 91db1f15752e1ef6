#!/bin/bash
# controller.qp_iteration_budget against none, alternated, the same hour:
#   bash docs/benchmark-runs/2026-11-29/budget/run.sh OUT
set -e
out=${1:?usage: run.sh OUT}
mkdir -p "$out"
loop() { python3 -c "import time;t=time.time();s=0
for i in range(3000000): s+=i
print(f'loop {time.time()-t:.2f} s')"; }
loop | tee "$out/loop_before.txt"
for round in 1 2; do
  for b in 0 100; do
    sm2ith bench --robot all --humans 10 --steps 200 \
      --scenario_text "{controller: {qp_iteration_budget: $b}}" \
      --json "$out/10p_budget${b}_run${round}.json" | tee "$out/10p_budget${b}_run${round}.txt"
  done
done
for b in 0 100; do
  sm2ith bench --robot all --humans 3 --steps 200 \
    --scenario_text "{controller: {qp_iteration_budget: $b}}" \
    --json "$out/3p_budget${b}.json" | tee "$out/3p_budget${b}.txt"
done
loop | tee "$out/loop_after.txt"
