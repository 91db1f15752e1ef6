#!/bin/bash
# controller.lazy_line_margin (the default, 0.25) against none (0: the
# controller before), alternated, the same hour; then the shipped controller
# with 3 and 0 people, the opt-in budget on it, and a profile:
#   bash docs/benchmark-runs/2026-11-29/lazy-lines/run.sh OUT
set -e
out=${1:?usage: run.sh OUT}
mkdir -p "$out"
loop() { python3 -c "import time;t=time.time();s=0
for i in range(3000000): s+=i
print(f'loop {time.time()-t:.2f} s')"; }
loop | tee "$out/loop_before.txt"
for round in 1 2 3; do
  for m in 0 0.25; do
    sm2ith bench --robot all --humans 10 --steps 200 \
      --scenario_text "{controller: {lazy_line_margin: $m}}" \
      --json "$out/10p_margin${m}_run${round}.json" | tee "$out/10p_margin${m}_run${round}.txt"
  done
done
for h in 3 0; do
  sm2ith bench --robot all --humans $h --steps 200 \
    --json "$out/${h}p.json" | tee "$out/${h}p.txt"
done
sm2ith bench --robot all --humans 10 --steps 200 --repeat 2 \
  --scenario_text "{controller: {qp_iteration_budget: 100}}" \
  --json "$out/10p_budget100.json" | tee "$out/10p_budget100.txt"
sm2ith bench --robot all --humans 3 --steps 200 --repeat 2 \
  --scenario_text "{controller: {time_step: 0.1, horizon: 20}}" \
  --json "$out/3p_10hz.json" | tee "$out/3p_10hz.txt"
sm2ith bench --robot all --humans 10 --steps 200 --profile \
  --json "$out/10p_profile.json" | tee "$out/10p_profile.txt"
for h in 1 2 5; do
  sm2ith bench --robot all --humans $h --steps 200 \
    --json "$out/scaling_${h}p.json" | tee "$out/scaling_${h}p.txt"
done
for h in 15 20; do
  sm2ith bench --robot all --humans $h --steps 50 \
    --json "$out/scaling_${h}p.json" | tee "$out/scaling_${h}p.txt"
done
loop | tee "$out/loop_after.txt"
