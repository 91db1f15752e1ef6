"""SM²ITH's `safe` runs among ORCA people with ``safety.turn_monitoring:
true`` against the shipped default (off), run for run (README, Contact in the
`safe` variant): at 10 seeds against ``../final-19b15d2``, at 30 seeds
against ``../seeds-30-19b15d2`` (banner/cup, pick-and-place) and
``../doorway-30-2026-11-28/19b15d2/sm2ith`` (the Stretch 3 doorway).

    D=docs/experiments/turn-monitoring
    T="{safety: {turn_monitoring: true}}"
    for s in banner_cup pick_and_place doorway; do
      sm2ith experiment $s --variant safe --people orca --methods SM2ITH \\
          --scenario_text "$T" --jobs 2 --out $D/seeds-10
    done
    for s in banner_cup pick_and_place; do
      sm2ith experiment $s --runs 30 --variant safe --people orca \\
          --methods SM2ITH --scenario_text "$T" --jobs 2 --out $D/seeds-30
    done
    sm2ith experiment doorway --only doorway_stretch3 --runs 30 \\
        --variant safe --people orca --methods SM2ITH --scenario_text "$T" \\
        --jobs 2 --out $D/seeds-30
    python $D/compare.py > $D/compare.txt
"""

import importlib.util
from pathlib import Path

HERE = Path(__file__).resolve().parent
_spec = importlib.util.spec_from_file_location(
    "paired_option", HERE.parent / "paired_option.py"
)
paired = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(paired)

PARTS = [
    ("seeds-10", "banner_cup", "final-19b15d2"),
    ("seeds-10", "pick_and_place", "final-19b15d2"),
    ("seeds-10", "doorway", "final-19b15d2"),
    ("seeds-30", "banner_cup", "seeds-30-19b15d2"),
    ("seeds-30", "pick_and_place", "seeds-30-19b15d2"),
    ("seeds-30", "doorway", "doorway-30-2026-11-28/19b15d2/sm2ith"),
]

for here, study, base in PARTS:
    print(f"\n## {here}: {study} against {base}")
    paired.BASE = HERE.parent / base
    paired.Compare(HERE / here, study, ("robot", "people"))
