"""A campaign's runs against another's on the same seeds, or against the
shipped controller's (docs/experiments/no-closer/compare.py: its metrics,
pairing and CIs), method by method and people model by people model.

    python docs/experiments/joint-peaks/compare.py NEW [BASE|shipped] [METHOD ...]
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parents[1] / "no-closer"))
from compare import AddClosing, ClosingMm, Compare, Runs, Shipped  # noqa: E402

BASE_CLOSING = Path(__file__).parents[1] / "no-closer" / "closing_shipped.csv"


def main(argv):
    new_dir = Path(argv[0])
    base_dir = argv[1] if len(argv) > 1 else "shipped"
    methods = argv[2:] or ["SM2ITH"]
    closing = ClosingMm(BASE_CLOSING)
    for robot in ("stretch3", "ridgeback_ur10"):
        for people in ("orca", "instructed", "social_force"):
            for method in methods:
                new = Runs(new_dir / "doorway.csv", method, people, robot)
                if not new:
                    continue
                if base_dir == "shipped":
                    base = Shipped(method, people, robot)
                else:
                    base = Runs(Path(base_dir) / "doorway.csv", method, people, robot)
                if not set(new) & set(base):
                    continue
                AddClosing(new, {})
                AddClosing(base, closing)
                Compare(new, base, f"{robot}, {method}, {people}")


if __name__ == "__main__":
    main(sys.argv[1:])
