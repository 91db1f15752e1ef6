#!/bin/bash
# The three rounds of rounds.txt: base, rounds1, g0.3, g0.15, all, base; then twice g0.15, base.
cd "$(dirname "$0")"
for v in base rounds1 g0.3 g0.15 all base; do for r in ridgeback_ur10 stretch3; do python var_bench.py $r $v | grep "^$v"; done; done
for i in 1 2; do for v in g0.15 base; do for r in ridgeback_ur10 stretch3; do python var_bench.py $r $v | grep "^$v"; done; done; done
