#!/bin/bash
# The end of 2026-11-29's tenth session: issue 13's figures on the shipped
# controller (the plans of 19b15d2 / b6dab5b; df7a7ac was reverted).
#   bash docs/benchmark-runs/2026-11-29/session-end-10/run.sh OUT
set -e
OUT=$(mkdir -p "${1:?output directory}" && cd "$1" && pwd)
loop() { python -c "import time; t=time.perf_counter(); s=0
for i in range(3000000): s+=i
print(f'loop {time.perf_counter()-t:.2f} s')" >> "$OUT/loop.txt"; }
loop
sm2ith bench --robot all --humans 3 --steps 200 --repeat 3 --json "$OUT/3p_repeat3.json" > "$OUT/3p_repeat3.txt" 2>&1
sm2ith bench --robot all --humans 0 --steps 200 --json "$OUT/0p.json" > "$OUT/0p.txt" 2>&1
sm2ith bench --robot all --humans 10 --steps 200 --json "$OUT/10p.json" > "$OUT/10p.txt" 2>&1
loop
