"""Studies re-run with ``controller: {qp_solver: auto}`` (2026-11-27, the
code of the README's Benchmark), paired run for run with the final re-run
(``../final``, commit bfe42b6, qp_solver piqp): per study and method, the
totals and paired differences with bootstrap CIs.

    sm2ith experiment adversarial --variant paper,safe --people orca,instructed,social_force --jobs 2 --out docs/experiments/auto-rerun --scenario_text '{controller: {qp_solver: auto}}'
    sm2ith experiment pursuer --variant paper,safe --jobs 2 --out docs/experiments/auto-rerun --scenario_text '{controller: {qp_solver: auto}}'
    sm2ith experiment banner_cup --variant paper,safe --people orca,instructed,social_force --jobs 2 --out docs/experiments/auto-rerun --scenario_text '{controller: {qp_solver: auto}}'
    sm2ith experiment pick_and_place --variant paper,safe --people orca,instructed,social_force --jobs 2 --out docs/experiments/auto-rerun --scenario_text '{controller: {qp_solver: auto}}'
    sm2ith experiment doorway --variant paper,safe --people orca,instructed,social_force --jobs 2 --out docs/experiments/auto-rerun --scenario_text '{controller: {qp_solver: auto}}'
    python docs/experiments/auto-rerun/summary.py

(auto is the default since 2026-11-27: the --scenario_text changes nothing
there.) The README's tables: python docs/experiments/final/summary.py
docs/experiments/auto-rerun
"""  # noqa: E501

import importlib.util
from pathlib import Path

import numpy as np

from sm2ith_drake.experiments.campaign import ReadRows
from sm2ith_drake.experiments.statistics import PairedDifference

HERE = Path(__file__).parent
COUNTS = ("success", "collision", "robot_closing_contact", "fallbacks")
METRICS = COUNTS + ("time_to_goal", "ee_error_mean", "base_retreat", "min_human_gap")


def Compare(study):
    path = HERE / f"{study}.csv"
    if not path.exists():
        return
    new = {r["run_id"]: r for r in ReadRows(path)}
    old = {
        r["run_id"]: r
        for r in ReadRows(HERE.parent / "final" / f"{study}.csv")
        if r["run_id"] in new
    }
    for method in sorted({r["method"] for r in new.values()}):
        ids = sorted(i for i in old if new[i]["method"] == method)
        print(f"\n{study}, {method}: auto − piqp (bfe42b6), {len(ids)} pairs")
        for key in METRICS:
            x = np.array([float(new[i][key]) for i in ids])
            y = np.array([float(old[i][key]) for i in ids])
            ok = np.isfinite(x) & np.isfinite(y)
            e = PairedDifference(x[ok], y[ok])
            total = key in COUNTS
            sx = np.nansum(x) if total else np.nanmedian(x)
            sy = np.nansum(y) if total else np.nanmedian(y)
            label = "total" if total else "median"
            print(
                f"  {key:22s} {label} {sx:9.4f} vs {sy:9.4f}   "
                f"mean difference {e.value:+.4f} [{e.low:+.4f}, {e.high:+.4f}]"
            )


def Verdicts():
    """Every per-cell verdict of the findings (findings.md) here and in the
    final re-run; the ones that differ (final-2026-11-28/compare.py's)."""
    path = HERE.parent / "final-2026-11-28" / "compare.py"
    spec = importlib.util.spec_from_file_location("compare", path)
    compare = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(compare)
    compare.ChangedVerdicts(HERE, HERE.parent / "final")


if __name__ == "__main__":
    for study in ("adversarial", "pursuer", "banner_cup", "pick_and_place", "doorway"):
        Compare(study)
    Verdicts()
