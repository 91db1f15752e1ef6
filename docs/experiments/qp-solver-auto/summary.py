"""Paired comparisons behind the README's Benchmark (the stage QPs' solver,
2026-11-27): SM²ITH's runs with the new default (``auto``: HPIPM for small
stage QPs, PIQP's generic build for the rest, empty slots pinned) against
the old one (``piqp_avx512``: PIQP alone, the AVX-512 build PIQP picks on
this machine; commit ead1de4 and e633451, which it reproduces run for run),
on the same seeds. Also: PIQP's generic build alone, PIQP solved to 1e-9,
and ``auto`` before empty slots were pinned (its QPs with empty slots went
to PIQP after HPIPM stalled). And the Stretch 3 doorway (``doorway/``,
SM²ITH at 68c389d with the new default) against the README's figures
(``../final/doorway.csv``, commit bfe42b6), per person count, and against
the same code with ``qp_solver: piqp`` (``doorway_piqp/``: CVMM and React,
instructed people, ``safe``, seeds 0-29; SM²ITH seeds 0-9), which
reproduces the final re-run's CVMM and React arrivals: why auto is not the
default.

    python docs/experiments/qp-solver-auto/summary.py
"""

from pathlib import Path

import numpy as np

from sm2ith_drake.experiments.campaign import ReadRows
from sm2ith_drake.experiments.statistics import PairedDifference

HERE = Path(__file__).parent
COUNTS = ("success", "collision", "robot_closing_contact", "fallbacks")
METRICS = COUNTS + (
    "time_to_goal",
    "ee_error_mean",
    "ee_error_max",
    "progress_share",
    "base_retreat",
    "min_human_gap",
    "freezing_time",
    "intimate_space_time_base",
)


def _Rows(name, keep):
    return {r["run_id"]: r for r in ReadRows(HERE / f"{name}.csv") if keep(r)}


def Compare(study, new, base, keep=lambda r: True, title="", rows=None):
    a, b = rows or (_Rows(f"{study}_{new}", keep), _Rows(f"{study}_{base}", keep))
    ids = sorted(set(a) & set(b))
    print(f"\n{study}: {new} − {base}, {len(ids)} pairs {title}")
    for key in METRICS:
        x = np.array([float(a[i][key]) for i in ids])
        y = np.array([float(b[i][key]) for i in ids])
        e = PairedDifference(x, y)
        total = key in COUNTS
        sx = np.nansum(x) if total else np.nanmedian(x)
        sy = np.nansum(y) if total else np.nanmedian(y)
        label = "total" if total else "median"
        print(
            f"  {key:26s} {label} {sx:9.4f} vs {sy:9.4f}   "
            f"mean difference {e.value:+.4f} [{e.low:+.4f}, {e.high:+.4f}]"
        )


def Seeds(lo, hi, people="orca"):
    return lambda r: r["people"] == people and lo <= int(r["seed"]) < hi


def Doorway():
    """The Stretch 3 doorway at 68c389d (the new default; ``doorway/``)
    against the README's figures at bfe42b6 (``../final/doorway.csv``,
    seeds 0-9, and ``../doorway-30-final/doorway.csv``, the instructed
    cells' 30 seeds), per method and cell."""
    new = _Rows("doorway/doorway", lambda r: True)
    old = {}
    for name in ("doorway-30-final", "final"):
        for r in ReadRows(HERE.parent / name / "doorway.csv"):
            if r["run_id"] in new:
                old[r["run_id"]] = r
    for method in ("SM2ITH", "CVMM", "React"):
        mine = {i: r for i, r in new.items() if r["method"] == method}
        if not mine:
            continue
        Compare("doorway", "auto", "bfe42b6", rows=(mine, old), title=method)
        cells = sorted({(r["people"], r["variant"]) for r in mine.values()})
        for people, variant in cells:
            reached = []
            for humans in (1, 2, 3, 5):
                ids = [
                    i
                    for i, r in mine.items()
                    if (r["people"], r["variant"], int(r["humans"]))
                    == (people, variant, humans)
                ]
                reached.append(
                    f"{sum(int(new[i]['success']) for i in ids)}"
                    f" vs {sum(int(old[i]['success']) for i in ids)} of {len(ids)}"
                )
            label = f"  {people:10s} {variant:5s} by count 1/2/3/5: "
            print(label + ", ".join(reached))


def DoorwayPiqp():
    """auto against piqp on the same code, and piqp against bfe42b6."""
    piqp = _Rows("doorway_piqp/doorway", lambda r: True)
    auto = _Rows("doorway/doorway", lambda r: r["run_id"] in piqp)
    final = {}
    for name in ("doorway-30-final", "final"):
        for r in ReadRows(HERE.parent / name / "doorway.csv"):
            if r["run_id"] in piqp:
                final[r["run_id"]] = r
    for method in ("SM2ITH", "CVMM", "React"):
        a = {i: r for i, r in auto.items() if r["method"] == method}
        Compare("doorway", "auto", "piqp", rows=(a, piqp), title=method)
        p = {i: r for i, r in piqp.items() if r["method"] == method}
        Compare("doorway", "piqp", "bfe42b6", rows=(p, final), title=method)


if __name__ == "__main__":
    Doorway()
    DoorwayPiqp()
    Compare("adversarial", "auto", "piqp_avx512")
    Compare("adversarial", "piqp_generic", "piqp_avx512")
    Compare("banner_cup", "auto", "piqp_avx512", Seeds(0, 40), "(ORCA, seeds 0-39)")
    Compare(
        "banner_cup",
        "auto",
        "piqp_avx512",
        Seeds(0, 10, "instructed"),
        "(instructed, seeds 0-9)",
    )
    Compare("banner_cup", "piqp_generic", "piqp_avx512", lambda r: int(r["seed"]) < 10)
    Compare("banner_cup", "piqp_tight", "piqp_avx512", Seeds(0, 10), "(ORCA)")
    for lo, hi in ((0, 10), (10, 20), (20, 40), (0, 40)):
        Compare(
            "banner_cup",
            "auto_slots_free",
            "piqp_avx512",
            Seeds(lo, hi),
            f"(ORCA, seeds {lo}-{hi - 1})",
        )
