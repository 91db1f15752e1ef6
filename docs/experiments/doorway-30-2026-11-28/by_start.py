"""The Stretch 3 doorway with instructed people, 30 seeds per count (this
directory's ``doorway.csv``, the default controller): each method's
arrivals split by where the people start, paired on the same seeds:
runs in which everyone comes toward the robot through the door
(oncoming) against runs in which someone starts behind the robot and
walks the same way (it catches up: people walk 0.5–1.5 m/s, the Stretch 3
0.3 m/s). No simulation: the split reads each run's scenario.

    python docs/experiments/doorway-30-2026-11-28/by_start.py

Output: by_start.txt.
"""

from pathlib import Path

from sm2ith_drake.experiments.campaign import ReadRows
from sm2ith_drake.experiments.runs import LoadRunScenario, SpecFromRow
from sm2ith_drake.experiments.statistics import PairedDifference
from sm2ith_drake.experiments.studies import STUDIES

HERE = Path(__file__).resolve().parent
METHODS = ("SM2ITH", "CVMM", "React")
COUNTS = (1, 2, 3, 5)


def main():
    rows = [
        r
        for r in ReadRows(HERE / "doorway.csv")
        if (r["robot"], r["people"]) == ("stretch3", "instructed")
    ]
    ok = {
        (r["variant"], r["humans"], r["method"], r["seed"]): float(r["success"] is True)
        for r in rows
    }
    behind = {}
    for r in rows:
        key = (r["humans"], r["seed"])
        if key not in behind:
            people = LoadRunScenario(SpecFromRow(STUDIES["doorway"], r)).humans
            behind[key] = sum(h.start[1] < 0 for h in people)
    lines = [
        "Stretch 3 doorway, instructed people, the default controller: arrivals "
        "by where the people start (oncoming: everyone comes through the door "
        "toward the robot; behind: at least one starts behind the robot and "
        "walks the same way); SM2ITH - method, paired [95 % CI]"
    ]
    for variant in ("safe", "paper"):
        for count in (None, *COUNTS):
            for group in ("oncoming", "behind"):
                keys = sorted(
                    k
                    for k, b in behind.items()
                    if (count is None or k[0] == count)
                    and (b == 0) == (group == "oncoming")
                )
                if not keys:
                    continue
                arrived = {
                    m: [ok[(variant, h, m, s)] for h, s in keys] for m in METHODS
                }
                label = "pooled" if count is None else f"{count} people"
                text = f"  {variant:5s} {label:9s} {group:8s} {len(keys):3d} runs:"
                text += "".join(f" {m} {int(sum(arrived[m])):3d}" for m in METHODS)
                for m in METHODS[1:]:
                    e = PairedDifference(arrived["SM2ITH"], arrived[m])
                    text += f" | vs {m} {e.value:+.2f} [{e.low:+.2f}, {e.high:+.2f}]"
                lines.append(text)
    text = "\n".join(lines)
    print(text)
    (HERE / "by_start.txt").write_text(text + "\n")


if __name__ == "__main__":
    main()
