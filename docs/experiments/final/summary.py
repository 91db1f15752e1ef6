"""The README's doorway and contact tables from this directory's CSVs.

python summary.py
"""

import csv
from collections import defaultdict
from pathlib import Path

HERE = Path(__file__).resolve().parent
PEOPLE = ("orca", "instructed", "social_force")
VARIANTS = ("paper", "safe")
COUNTS = ("1", "2", "3", "5")
ROBOTS = (("stretch3", "Stretch 3"), ("ridgeback_ur10", "Ridgeback–UR10"))


def Rows(study):
    with open(HERE / f"{study}.csv", newline="") as f:
        return list(csv.DictReader(f))


def Yes(r, key):
    return r[key] == "True"


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
                    deepest = (
                        f"{-1e3 * min(float(r['min_human_gap']) for r in hit):.0f}"
                    )
            print(
                f"| {study.replace('_', '-')} | {people.replace('_', ' ')} | "
                f"{variant} | " + " | ".join(out) + f" | {n} | {deepest} |"
            )


def WallTimes():
    import json

    print()
    for f in sorted(HERE.glob("*_timing.json")):
        for t in json.loads(f.read_text()):
            print(
                f"{f.stem.removesuffix('_timing')}: {t['runs']} runs in "
                f"{t['wall_time_s'] / 60:.1f} min (--jobs {t['jobs']}, {t['date']})"
            )


COLUMNS = [(p, v) for p in PEOPLE for v in VARIANTS]
LABELS = {"orca": "ORCA", "instructed": "instructed", "social_force": "social force"}
ROBOT_LABELS = dict(ROBOTS)


def _Signed(text):
    """'0.0013 [-0.002, 0.004]' with signs: '+0.0013 [−0.002, +0.004]'."""
    import re

    return re.sub(r"(?<![\w.\-])(\d)", r"+\1", text).replace("-", "−")


def WhatHolds():
    """findings.md pivoted as in the README: a row per claim (and robot), a
    column per people model and variant."""
    table, order = {}, []
    for line in (HERE / "findings.md").read_text().splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) != 7 or cells[0] == "finding" or cells[0].startswith("-"):
            continue
        key, claim, robot, people, variant, diffs, verdict = cells
        robots = {r for (k, c, r) in order if (k, c) == (key, claim)}
        row = (key, claim, robot)
        if row not in order:
            order.append(row)
        verdict = verdict.strip("*")
        if verdict == "not distinguishable":
            text = "n.d."
        else:
            values = "; ".join(
                _Signed(d.split(": ", 1)[1].rsplit(" (n=", 1)[0])
                for d in diffs.split("; ")
            )
            text = f"**{verdict}** ({values})"
        table[(row, people, variant)] = text
        del robots
    header = " | ".join(f"{LABELS[p]} `{v}`" for p, v in COLUMNS)
    print(f"\n| finding | {header} |")
    print("|---" * (len(COLUMNS) + 1) + "|")
    multi = {}
    for key, claim, robot in order:
        multi.setdefault((key, claim), set()).add(robot)
    for key, claim, robot in order:
        name = f"{key} {claim}"
        if len(multi[(key, claim)]) > 1:
            name = f"{key} {ROBOT_LABELS.get(robot, robot)}: {claim}"
        cells = [table.get(((key, claim, robot), p, v), "–") for p, v in COLUMNS]
        print(f"| {name} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    Doorway()
    WhatHolds()
    Contacts()
    WallTimes()
