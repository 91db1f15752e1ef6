"""SM²ITH's `safe` runs among ORCA people with ``safety.turn_monitoring:
true`` against the shipped default (off), run for run, as
``../guard-hold-c5f5f76/compare.py`` does (its commands, with
``T="{safety: {turn_monitoring: true}}"`` and ``D`` this directory;
``seeds-30-floor-0.4`` adds ``turn_speed_floor: 0.4`` at 30 seeds;
``seeds-30-fixed`` is the option as shipped, its warm start within the
bounds, floor 0.4; the sets before it were measured with a warm start
outside the bounds, README.md).

    python docs/experiments/turn-monitoring/compare.py > \
        docs/experiments/turn-monitoring/compare.txt
"""

import importlib.util
from pathlib import Path

HERE = Path(__file__).resolve().parent
_spec = importlib.util.spec_from_file_location(
    "guard_hold_compare", HERE.parent / "guard-hold-c5f5f76" / "compare.py"
)
hold = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(hold)

later = [
    (sub, study, base)
    for sub in (
        "seeds-30-floor-0.4",
        "seeds-30-fixed",
        "seeds-30-retry",
        "seeds-30-restore",
    )
    for _, study, base in hold.PARTS[3:]
]
hold.CompareAll(HERE, hold.PARTS + later)
