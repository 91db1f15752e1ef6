"""The final re-run of 2026-11-28 against that of 2026-11-27, run for run.

Per study, method and variant (pooled over robots, people models and
counts): arrivals and runs with contact, new against old; then every
paired metric whose 95 % bootstrap CI excludes 0, per study, method,
variant and people model; then the per-cell verdicts of the findings that
changed. Studies not yet complete here are paired on the runs they have.

    python docs/experiments/final-2026-11-28/compare.py [NEW_DIR [OLD_DIR]]
"""

import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

from sm2ith_drake.experiments.campaign import ReadRows
from sm2ith_drake.experiments.findings import FindingRows
from sm2ith_drake.experiments.statistics import PairedDifference
from sm2ith_drake.experiments.studies import STUDIES

NEW = Path(__file__).parent
OLD = NEW.parent / "final-2026-11-27"
TOTALS = ("success", "collision", "robot_closing_contact", "fallbacks")
PAIRED = TOTALS + (
    "time_to_goal",
    "freezing_time",
    "progress_share",
    "base_retreat",
    "ee_error_mean",
    "ee_error_max",
    "base_path_deviation",
    "navigation_time",
    "min_human_gap",
    "intimate_space_time_base",
)


def Number(row, key):
    value = row.get(key)
    if value is None or value == "":
        return np.nan
    return float(value)


def Pairs(study):
    """(new, old) rows of the runs both directories have."""
    if not (NEW / f"{study}.csv").exists():
        return []
    new = {r["run_id"]: r for r in ReadRows(NEW / f"{study}.csv")}
    old = {r["run_id"]: r for r in ReadRows(OLD / f"{study}.csv")}
    return [(new[i], old[i]) for i in sorted(set(new) & set(old))]


def Grouped(pairs, keys):
    groups = defaultdict(list)
    for new, old in pairs:
        groups[tuple(new[k] for k in keys)].append((new, old))
    return groups


def Totals(study, pairs):
    groups = Grouped(pairs, ("method", "variant"))
    for (method, variant), group in sorted(groups.items()):
        text = []
        for key in TOTALS:
            x = sum(Number(n, key) > 0 for n, _ in group)
            y = sum(Number(o, key) > 0 for _, o in group)
            text.append(f"{key} {x} vs {y}")
        print(f"  {study} {method} {variant} ({len(group)} pairs): " + ", ".join(text))


def Distinguishable(study, pairs):
    """Paired differences whose CI excludes 0; returns (found, varying)."""
    found = varying = 0
    keys = ("method", "variant", "people", "robot")
    for group_key, group in sorted(Grouped(pairs, keys).items()):
        for key in PAIRED:
            x = np.array([Number(n, key) for n, _ in group])
            y = np.array([Number(o, key) for _, o in group])
            ok = np.isfinite(x) & np.isfinite(y)
            if ok.sum() < 2 or np.all(x[ok] == y[ok]):
                continue
            varying += 1
            e = PairedDifference(x[ok], y[ok])
            if e.low > 0 or e.high < 0:
                found += 1
                print(
                    f"  {study} {' '.join(group_key)} {key}: "
                    f"{e.value:+.4g} [{e.low:+.4g}, {e.high:+.4g}] (n = {ok.sum()})"
                )
    return found, varying


def ChangedVerdicts(new_dir=None, old_dir=None):
    """Prints the per-cell verdicts of the findings that differ between
    two study directories (default NEW and OLD), with the new CIs."""
    new_dir, old_dir = new_dir or NEW, old_dir or OLD
    changed, total = [], 0
    for name, study in STUDIES.items():
        paths = [new_dir / f"{name}.csv", old_dir / f"{name}.csv"]
        if not study.findings or not all(p.exists() for p in paths):
            continue
        rows = [ReadRows(p) for p in paths]
        if len(rows[0]) < len(rows[1]):
            print(f"  {name}: {len(rows[0])} of {len(rows[1])} runs, not compared")
            continue
        new, old = (
            {
                (e["key"], e["claim"], e["humans"], e["people"], e["variant"]): e
                for e in FindingRows(study, r)
            }
            for r in rows
        )
        for key in sorted(set(new) & set(old), key=str):
            total += 1
            if new[key]["verdict"] != old[key]["verdict"]:
                changed.append((key, old[key], new[key]))
    print(f"findings: {len(changed)} of {total} per-cell verdicts differ")
    for (finding, claim, humans, people, variant), was, now in changed:
        count = f", {'/'.join(map(str, humans))} people" if humans else ""
        values = "; ".join(
            f"{label} {e.value:+.3g} [{e.low:+.3g}, {e.high:+.3g}]"
            for label, e in now["comparisons"]
        )
        print(
            f"  {finding} {claim}{count} ({people}, {variant}): "
            f"{was['verdict']} -> {now['verdict']} ({values})"
        )


if __name__ == "__main__":
    if len(sys.argv) > 1:
        NEW = Path(sys.argv[1])
        OLD = Path(sys.argv[2]) if len(sys.argv) > 2 else NEW.parent / OLD.name
    print(f"{NEW} against {OLD}")
    print("runs with (arrival, contact, robot closing in, fallback), new vs old:")
    pairs = {study: Pairs(study) for study in STUDIES}
    pairs = {study: runs for study, runs in pairs.items() if runs}
    for study, runs in pairs.items():
        Totals(study, runs)
    print("paired differences whose 95 % CI excludes 0 (mean [CI]):")
    for study, runs in pairs.items():
        found, varying = Distinguishable(study, runs)
        print(f"  {study}: {found} of {varying} varying paired metrics")
    ChangedVerdicts()
