"""SM²ITH with the stall recovery (`controller.recovery.enabled: true`;
DIRECTORY/adversarial.csv, default headon-recovery) against SM²ITH and
CVMM with the defaults (adversarial.csv), on the head-on cell's 30
seeds: arrivals, time to goal, the (d) metrics and contact, paired by seed
within each people model and variant.

python docs/experiments/seeds-30-2026-11-28/headon_recovery.py [DIRECTORY]
"""

import sys
from pathlib import Path

from sm2ith_drake.experiments.campaign import ReadRows
from sm2ith_drake.experiments.findings import Paired
from sm2ith_drake.experiments.statistics import PairedDifference

HERE = Path(__file__).parent
METRICS = ("success", "time_to_goal", "progress_share", "base_retreat", "collision")


def _HeadOn(path):
    return [
        r for r in ReadRows(path) if r["status"] == "ok" and r["family"] == "headon"
    ]


def main(directory):
    default = _HeadOn(HERE / "adversarial.csv")
    lever = _HeadOn(HERE / directory / "adversarial.csv")
    for r in lever:
        r["method"] = "SM2ITH+recovery"
    print("mean over 30 seeds; differences paired by seed: mean [95 % CI]\n")
    print(
        "| people | variant | metric | SM²ITH+recovery | SM²ITH | CVMM "
        "| +recovery − SM²ITH | +recovery − CVMM |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for people in ("orca", "instructed", "social_force"):
        for variant in ("paper", "safe"):
            rows = [
                r
                for r in default + lever
                if r["people"] == people and r["variant"] == variant
            ]
            for metric in METRICS:
                cells, means = [], {}
                for other in ("SM2ITH", "CVMM"):
                    a, b = Paired(rows, metric, "SM2ITH+recovery", other)
                    d = PairedDifference(a, b)
                    means["SM2ITH+recovery"] = sum(a) / len(a)
                    means[other] = sum(b) / len(b)
                    cells.append(f"{d.value:+.3g} [{d.low:+.3g}, {d.high:+.3g}]")
                values = " | ".join(
                    f"{means[m]:.3g}" for m in ("SM2ITH+recovery", "SM2ITH", "CVMM")
                )
                print(
                    f"| {people} | {variant} | {metric} | {values} | "
                    + " | ".join(cells)
                    + " |"
                )


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "headon-recovery")
