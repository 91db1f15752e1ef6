"""SM²ITH's doorway arrivals at 30 seeds per count, 19b15d2 against e176d82,
run for run (the same seeds): per people model and variant, pooled over the
counts and at 3 people, the paired difference with its 95 % bootstrap CI.

    python docs/experiments/doorway-30-2026-11-28/19b15d2/paired.py

Output: paired.txt."""

import importlib.util
from pathlib import Path

from sm2ith_drake.experiments.statistics import PairedDifference

HERE = Path(__file__).resolve().parent
_spec = importlib.util.spec_from_file_location("summary_19b15d2", HERE / "summary.py")
NEW = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(NEW)
OLD = NEW.BEFORE


def main():
    lines = []
    for (people, variant), sources in OLD.CELLS.items():
        directory = sources["SM2ITH"]
        new = NEW.Rows(directory, people, variant, "SM2ITH")
        old = OLD.Rows(directory, people, variant, "SM2ITH")
        text = f"{people:12s} {variant:5s}"
        for label, keys in (
            ("all counts", sorted(set(new) & set(old))),
            ("3 people", sorted(k for k in set(new) & set(old) if k[0] == 3)),
        ):
            a = [float(new[k]["success"] is True) for k in keys]
            b = [float(old[k]["success"] is True) for k in keys]
            e = PairedDifference(a, b)
            text += (
                f" | {label}: {int(sum(a))} against {int(sum(b))} of {len(keys)},"
                f" {e.value:+.3f} [{e.low:+.3f}, {e.high:+.3f}]"
            )
        lines.append(text)
    text = "\n".join(lines)
    print(text)
    (HERE / "paired.txt").write_text(text + "\n")


if __name__ == "__main__":
    main()
