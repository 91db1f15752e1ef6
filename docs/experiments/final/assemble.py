"""Assembles this directory's CSVs from the earlier campaigns whose runs the
final controller reproduces, leaving out the rows to be re-run.

The final controller is the default at the commit named in README.md here;
its plans equal those of commit c48edcd (checked run for run, README.md).
What changed since c48edcd is the instructed people (5d9d1e4), so:

- ORCA, social-force and the pursuer's rows: from ../rerun-c48edcd/.
- Instructed rows already re-run with the 5d9d1e4 people: the head-on
  study and the Ridgeback-UR10 doorway (../instructed-5d9d1e4/), the
  Stretch 3 doorway's `safe` cells, seeds 0-9 (../doorway-30-5d9d1e4/).
- Every other instructed row is left out: `sm2ith experiment` then runs
  exactly those (README.md here has the commands).

Rows of CSVs older than the `recovery_steps` column get 0 there: the
recovery from stalls did not exist or was off (it is off by default).

    python assemble.py   # overwrites ./*.csv
"""

import csv
from pathlib import Path

from sm2ith_drake.experiments.campaign import COLUMNS

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent


def Rows(path, keep):
    with open(ROOT / path, newline="") as f:
        return [r for r in csv.DictReader(f) if keep(r)]


def NotInstructed(r):
    return r["people"] != "instructed"


def Write(name, rows, out=HERE):
    ids = [r["run_id"] for r in rows]
    assert len(ids) == len(set(ids)), f"{name}: a run twice"
    with open(Path(out) / name, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=COLUMNS, extrasaction="raise")
        w.writeheader()
        for r in rows:
            w.writerow(
                {c: r.get(c, "0" if c == "recovery_steps" else "") for c in COLUMNS}
            )
    print(f"{name}: {len(rows)} rows")


def main():
    c48 = "rerun-c48edcd"
    Write(
        "adversarial.csv",
        Rows(f"{c48}/adversarial.csv", NotInstructed)
        + Rows("instructed-5d9d1e4/adversarial.csv", lambda r: True),
    )
    for study in ("banner_cup", "pick_and_place"):
        Write(f"{study}.csv", Rows(f"{c48}/{study}.csv", NotInstructed))
    Write("pursuer.csv", Rows(f"{c48}/pursuer.csv", lambda r: True))
    Write(
        "doorway.csv",
        Rows(f"{c48}/doorway.csv", NotInstructed)
        + Rows("instructed-5d9d1e4/doorway.csv", lambda r: True)
        + Rows(
            "doorway-30-5d9d1e4/doorway.csv",
            lambda r: (
                r["run_id"].startswith("doorway_stretch3_")
                and r["variant"] == "safe"
                and int(r["seed"]) < 10
            ),
        ),
    )


if __name__ == "__main__":
    main()
