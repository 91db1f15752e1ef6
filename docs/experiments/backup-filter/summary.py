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


def Pairs(path: Path) -> dict:
    """{(study, robot, people, variant, method): [(run, its default run)]}."""
    study = path.stem.split(".")[0]
    reference = {r["run_id"]: r for r in ReadRows(FINAL / f"{study}.csv")}
    cells = defaultdict(list)
    for r in ReadRows(path):
        if r["run_id"] in reference:
            cell = (study, r["robot"], r["people"], r["variant"], r["method"])
            cells[cell].append((r, reference[r["run_id"]]))
    return cells


def Pooled(paths, method: str, people: str):
    """Contacts over every study's runs of one method and people model."""
    pairs = [
        pair
        for path in paths
        for cell, cell_pairs in Pairs(path).items()
        if cell[4] == method and cell[2] == people
        for pair in cell_pairs
    ]
    print(f"pooled: {method}, {people} people, {len(pairs)} pairs (filter vs default)")
    for flag in ("collision", "robot_closing_contact"):
        new = [r[flag] is True for r, _ in pairs]
        old = [o[flag] is True for _, o in pairs]
        print(f"  {flag:22s} {sum(new):3d} vs {sum(old):3d}  {Ci(new, old)}")


def Summarize(path: Path):
    cells = Pairs(path)
    for cell, pairs in sorted(cells.items()):
        print(f"{path.name}: {' '.join(cell)}, {len(pairs)} pairs (filter vs default)")
        for flag in FLAGS:
            new = [r[flag] is True for r, _ in pairs]
            old = [o[flag] is True for _, o in pairs]
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
            counts[r["humans"]][0] += r["success"] is True
            counts[r["humans"]][1] += o["success"] is True
        print(
            "  arrivals by people count: "
            + ", ".join(f"{h}: {a} vs {b}" for h, (a, b) in sorted(counts.items()))
        )


if __name__ == "__main__":
    paths = sorted(HERE.glob("*.csv"))
    for csv_path in paths:
        Summarize(csv_path)
    # The filter as shipped: the files without an earlier commit's name.
    shipped = [p for p in paths if p.stem.count(".") == 1]
    Pooled(shipped, "SM2ITH", "orca")
