"""The backup filter measured (README, Contact in the `safe` variant):
each CSV here (`safety: {backup_filter: true}`, `safe` variant) paired run
for run with the final re-run's rows of the same run ids (the default
controller, ../final/), per method, robot and people model.

    python summary.py
"""

from collections import defaultdict
from pathlib import Path

import numpy as np

from sm2ith_drake.experiments.campaign import ReadRows
from sm2ith_drake.experiments.statistics import PairedDifference

HERE = Path(__file__).parent
FINAL = HERE.parent / "final"
FLAGS = ("success", "collision", "robot_closing_contact", "wall_collision")


def Ci(a, b):
    e = PairedDifference(np.asarray(a, float), np.asarray(b, float))
    return f"{e.value:+.2f} [{e.low:+.2f}, {e.high:+.2f}]"


def Summarize(path: Path):
    study = path.stem.split(".")[0]
    reference = {r["run_id"]: r for r in ReadRows(FINAL / f"{study}.csv")}
    cells = defaultdict(list)
    for r in ReadRows(path):
        if r["run_id"] in reference:
            cell = (study, r["robot"], r["people"], r["variant"], r["method"])
            cells[cell].append((r, reference[r["run_id"]]))
    for cell, pairs in sorted(cells.items()):
        print(f"{path.name}: {' '.join(cell)}, {len(pairs)} pairs (filter vs default)")
        for flag in FLAGS:
            new = [bool(r[flag]) for r, _ in pairs]
            old = [bool(o[flag]) for _, o in pairs]
            print(f"  {flag:22s} {sum(new):3d} vs {sum(old):3d}  {Ci(new, old)}")
        for column, scale, unit in (
            ("freezing_time", 1.0, "s"),
            ("time_to_goal", 1.0, "s"),
        ):
            new = np.array([r[column] for r, _ in pairs], float)
            old = np.array([o[column] for _, o in pairs], float)
            ok = np.isfinite(new) & np.isfinite(old)
            print(
                f"  {column:22s} median {np.nanmedian(new) * scale:.2f} vs "
                f"{np.nanmedian(old) * scale:.2f} {unit}"
                + (
                    f"  {Ci(new[ok], old[ok])} ({ok.sum()} pairs)"
                    if ok.sum() > 1
                    else ""
                )
            )
        gaps = [
            min(x["min_human_gap"] for x in side) for side in zip(*pairs, strict=True)
        ]
        print(
            f"  smallest gap {gaps[0] * 1e3:.0f} vs {gaps[1] * 1e3:.0f} mm "
            "(negative: the deepest contact)"
        )
        counts = defaultdict(lambda: [0, 0])
        for r, o in pairs:
            counts[r["humans"]][0] += bool(r["success"])
            counts[r["humans"]][1] += bool(o["success"])
        print(
            "  arrivals by people count: "
            + ", ".join(f"{h}: {a} vs {b}" for h, (a, b) in sorted(counts.items()))
        )


if __name__ == "__main__":
    for csv_path in sorted(HERE.glob("*.csv")):
        Summarize(csv_path)
