"""The studies as the shipped default runs them (2026-11-27): the re-run
with ``qp_solver: auto`` (``../auto-rerun``, all 3 040 runs) with the
rows that ``safety.guard_stopping_time`` (the default since then) changes
taken from its campaign (``../guard-stopping-ec27ad8``).

The flag changes only SM²ITH in the ``safe`` variant on the Ridgeback–UR10
(its guard holds 6 steps instead of 3; the Stretch 3's stopping time is
3 steps, so its rows are the same controller; CVMM, React, the weighted
sum and ``paper`` have no guard): the doorway's and pick-and-place's
Ridgeback–UR10 SM²ITH ``safe`` rows, 180 of them, run with the flag. Every
other row is copied as it is. The rows keep the ``scenario_text`` they ran
with (``safety: {guard_stopping_time: true}`` on the replaced ones).

    python docs/experiments/final-2026-11-27/merge.py

writes this directory's CSVs, reports, plots and ``findings.md``;
``python docs/experiments/final/summary.py docs/experiments/final-2026-11-27``
prints the README's tables.
"""

import csv
import json
from pathlib import Path

from sm2ith_drake.experiments.campaign import ReadRows
from sm2ith_drake.experiments.findings import WriteFindings
from sm2ith_drake.experiments.report import MakePlots, WriteReport
from sm2ith_drake.experiments.studies import STUDIES

HERE = Path(__file__).parent
BASE = HERE.parent / "auto-rerun"
GUARD = HERE.parent / "guard-stopping-ec27ad8"


def _Raw(path):
    with path.open(newline="") as f:
        reader = csv.DictReader(f)
        return reader.fieldnames, list(reader)


def Merge(name):
    columns, rows = _Raw(BASE / f"{name}.csv")
    replaced = 0
    if (GUARD / f"{name}.csv").exists():
        guard_columns, guard_rows = _Raw(GUARD / f"{name}.csv")
        assert guard_columns == columns, name
        new = {r["run_id"]: r for r in guard_rows}
        for i, row in enumerate(rows):
            if row["run_id"] in new:
                assert row["robot"] == "ridgeback_ur10" and row["method"] == "SM2ITH"
                assert row["variant"] == "safe"
                rows[i] = new.pop(row["run_id"])
                replaced += 1
        assert not new, f"{name}: rows not in the re-run: {sorted(new)[:3]}"
    with (HERE / f"{name}.csv").open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=columns)
        writer.writeheader()
        writer.writerows(rows)
    return len(rows), replaced


def _WallTime(name):
    path = BASE / f"{name}_timing.json"
    if not path.exists():
        return 0.0
    return sum(entry["wall_time_s"] for entry in json.loads(path.read_text()))


def main():
    for name, study in STUDIES.items():
        if not (BASE / f"{name}.csv").exists():
            continue
        total, replaced = Merge(name)
        rows = ReadRows(HERE / f"{name}.csv")
        plots = MakePlots(study, rows, HERE)
        WriteReport(
            study,
            rows,
            HERE,
            plots,
            wall_time_s=0.0,
            ran=0,
            study_wall_time_s=_WallTime(name),
        )
        print(f"{name}: {total} rows, {replaced} from the guard_stopping_time runs")
    WriteFindings(
        STUDIES, {name: ReadRows(HERE / f"{name}.csv") for name in STUDIES}, HERE
    )


if __name__ == "__main__":
    main()
