"""The KKT faithfulness of faithfulness_seeds.py (the crossing and corridor
scenarios) with the guard held for the base's stopping time from its
current speed (the patch of
docs/benchmark-runs/2026-11-27-late/guard_current_speed.py, not in the
product).

    python docs/benchmark-runs/2026-11-28/faithfulness_guard_current_speed.py 0-4
"""

import runpy
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parents[2]
patch = (DOCS / "benchmark-runs/2026-11-27-late/guard_current_speed.py").read_text()
exec(patch.split("HERE = ")[0])  # the patch, without its own measurement
sys.argv = ["faithfulness_seeds.py", *sys.argv[1:]]
runpy.run_path(str(DOCS / "experiments/qp-solver-auto/faithfulness_seeds.py"))
