#!/bin/bash
# The end of 2026-11-29's ninth session: issue 13's figures on the shipped
# controller, the profile, and the scaling table (0–20 people).
#   bash docs/benchmark-runs/2026-11-29/session-end-9/run.sh OUT
set -e
OUT=$(mkdir -p "${1:?output directory}" && cd "$1" && pwd)
loop() { python -c "import time; t=time.perf_counter(); s=0
for i in range(3000000): s+=i
print(f'loop {time.perf_counter()-t:.2f} s')" >> "$OUT/loop.txt"; }
loop
for run in 1 2 3; do
  sm2ith bench --robot all --humans 3 --steps 200 --json "$OUT/3p_run$run.json" > "$OUT/3p_run$run.txt" 2>&1
done
sm2ith bench --robot all --humans 0 --steps 200 --json "$OUT/0p.json" > "$OUT/0p.txt" 2>&1
sm2ith bench --robot all --humans 10 --steps 200 --json "$OUT/10p.json" > "$OUT/10p.txt" 2>&1
sm2ith bench --robot all --humans 3 --steps 200 --profile > "$OUT/3p_profile.txt" 2>&1
sm2ith bench --robot all --humans 10 --steps 200 --profile > "$OUT/10p_profile.txt" 2>&1
loop
for h in 1 2 5 15 20; do
  steps=200; [ $h -gt 10 ] && steps=50
  sm2ith bench --robot all --humans $h --steps $steps --json "$OUT/scaling_${h}p.json" > "$OUT/scaling_${h}p.txt" 2>&1
done
loop
