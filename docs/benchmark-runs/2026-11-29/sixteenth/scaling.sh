#!/bin/bash
# The scaling table on the sixteenth session's default (qp_iteration_budget 120).
OUT=${1:-.}  # run from the repository with the venv active
for h in 1 2 5; do sm2ith bench --robot all --humans $h --steps 200 --json $OUT/scaling_${h}p.json > $OUT/scaling_${h}p.txt 2>&1; done
for h in 15 20; do sm2ith bench --robot all --humans $h --steps 50 --json $OUT/scaling_${h}p.json > $OUT/scaling_${h}p.txt 2>&1; done
