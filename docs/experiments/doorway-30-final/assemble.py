"""Seeds this directory's doorway.csv (Stretch 3, instructed people, 30
seeds per count) with the runs the final controller has already made:

- `safe`, every method, seeds 0-29: ../doorway-30-5d9d1e4/ (the final
  controller's plans equal those of 5d9d1e4's, ../final/README.md);
- `paper`, every method, seeds 0-9: ../final/.

`sm2ith experiment doorway --only doorway_stretch3 --runs 30 --variant
paper,safe --people instructed --out .` then runs the `paper` seeds 10-29.

    python assemble.py   # overwrites ./doorway.csv
"""

import importlib.util
from pathlib import Path

HERE = Path(__file__).resolve().parent
_spec = importlib.util.spec_from_file_location(
    "final_assemble", HERE.parent / "final" / "assemble.py"
)
final = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(final)


def Stretch3Instructed(r):
    return r["robot"] == "stretch3" and r["people"] == "instructed"


def main():
    rows = final.Rows(
        "doorway-30-5d9d1e4/doorway.csv",
        lambda r: Stretch3Instructed(r) and r["variant"] == "safe",
    ) + final.Rows(
        "final/doorway.csv",
        lambda r: Stretch3Instructed(r) and r["variant"] == "paper",
    )
    final.Write("doorway.csv", rows, out=HERE)


if __name__ == "__main__":
    main()
