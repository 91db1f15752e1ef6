"""The README's doorway, findings and contact tables from this directory's
CSVs, or from another study directory's.

python summary.py [DIRECTORY]
"""

import json
import sys
from collections import defaultdict
from pathlib import Path

from sm2ith_drake.experiments.campaign import ReadRows
from sm2ith_drake.experiments.findings import FindingRows
from sm2ith_drake.experiments.studies import STUDIES

HERE = Path(sys.argv[1] if len(sys.argv) > 1 else Path(__file__).parent).resolve()
PEOPLE = ("orca", "instructed", "social_force")
VARIANTS = ("paper", "safe")
COUNTS = (1, 2, 3, 5)
ROBOTS = (("stretch3", "Stretch 3"), ("ridgeback_ur10", "Ridgeback–UR10"))


def Rows(study):
    return ReadRows(HERE / f"{study}.csv")


def Yes(r, key):
    return r[key] is True


def Doorway():
    rows = Rows("doorway")
    cell = defaultdict(list)
    for r in rows:
        cell[(r["robot"], r["people"], r["variant"], r["method"])].append(r)
    print(
        "| robot | people | variant | SM²ITH by count (1/2/3/5) | CVMM | React "
        "| SM²ITH contact-free arrivals | CVMM | React |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for robot, label in ROBOTS:
        for people in PEOPLE:
            for variant in VARIANTS:
                reached, clean = [], []
                for method in ("SM2ITH", "CVMM", "React"):
                    runs = cell[(robot, people, variant, method)]
                    ok = [r for r in runs if Yes(r, "success")]
                    by = "/".join(
                        str(sum(r["humans"] == h for r in ok)) for h in COUNTS
                    )
                    reached.append(f"{len(ok)}/{len(runs)} ({by})")
                    clean.append(str(sum(not Yes(r, "collision") for r in ok)))
                print(
                    f"| {label} | {people.replace('_', ' ')} | {variant} | "
                    + " | ".join(reached + clean)
                    + " |"
                )


def Contacts():
    print(
        "\n| study | people | variant | SM²ITH | CVMM | React | weighted sum "
        "| runs per method | SM²ITH deepest mm |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for study in ("adversarial", "banner_cup", "doorway", "pick_and_place", "pursuer"):
        rows = Rows(study)
        groups = sorted({(r["people"], r["variant"]) for r in rows})
        for people, variant in groups:
            out, n = [], 0
            deepest = "–"
            for method in ("SM2ITH", "CVMM", "React", "weighted_sum"):
                runs = [
                    r
                    for r in rows
                    if (r["people"], r["variant"], r["method"])
                    == (people, variant, method)
                ]
                if not runs:
                    out.append("–")
                    continue
                n = len(runs)
                hit = [r for r in runs if Yes(r, "collision")]
                closing = sum(Yes(r, "robot_closing_contact") for r in hit)
                out.append(f"{len(hit)} ({closing})")
                if method == "SM2ITH" and hit:
                    deepest = f"{-1e3 * min(r['min_human_gap'] for r in hit):.0f}"
            print(
                f"| {study.replace('_', '-')} | {people.replace('_', ' ')} | "
                f"{variant} | " + " | ".join(out) + f" | {n} | {deepest} |"
            )


def WallTimes():
    print()
    for f in sorted(HERE.glob("*_timing.json")):
        for t in json.loads(f.read_text()):
            print(
                f"{f.stem.removesuffix('_timing')}: {t['runs']} runs in "
                f"{t['wall_time_s'] / 60:.1f} min (--jobs {t['jobs']}, {t['date']})"
            )


COLUMNS = [(p, v) for p in PEOPLE for v in VARIANTS]
LABELS = {"orca": "ORCA", "instructed": "instructed", "social_force": "social force"}


def _Signed(x):
    return f"{x:+.3g}".replace("-", "−")


def WhatHolds():
    """The findings (experiments/findings.py, as in findings.md) as the
    README has them: a row per claim, a column per people model and
    variant; per-count doorway claims left to findings.md."""
    table, order = {}, []
    for name, study in STUDIES.items():
        path = HERE / f"{name}.csv"
        if not study.findings or not path.exists():
            continue
        for e in FindingRows(study, ReadRows(path)):
            if e["key"] == "doorway" and e["humans"]:
                continue
            row = f"{e['key']} {e['claim']}"
            if row not in order:
                order.append(row)
            if e["verdict"] == "not distinguishable":
                text = "n.d."
            else:
                values = "; ".join(
                    f"{_Signed(d.value)} [{_Signed(d.low)}, {_Signed(d.high)}]"
                    for _, d in e["comparisons"]
                )
                text = f"**{e['verdict']}** ({values})"
            table[(row, e["people"], e["variant"])] = text
    header = " | ".join(f"{LABELS[p]} `{v}`" for p, v in COLUMNS)
    print(f"\n| finding | {header} |")
    print("|---" * (len(COLUMNS) + 1) + "|")
    for row in order:
        cells = [table.get((row, p, v), "–") for p, v in COLUMNS]
        print(f"| {row} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    Doorway()
    WhatHolds()
    Contacts()
    WallTimes()
