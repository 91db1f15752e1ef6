"""The doorway measurements of 2026-11-25 (README, Doorway): paired
differences (mean, 95 % bootstrap CI) of SM²ITH variants against the
default controller and against CVMM and React on the same seeds.

    python summary.py
"""

import csv
from pathlib import Path

import numpy as np

from sm2ith_drake.experiments.statistics import PairedDifference

HERE = Path(__file__).parent
EXPERIMENTS = HERE.parent


def Rows(path, **match):
    if not path.exists():
        return []
    with open(path) as f:
        return [
            r
            for r in csv.DictReader(f)
            if all(r[key] == value for key, value in match.items())
        ]


def Keyed(rows, *columns):
    return {tuple(r[c] for c in columns): r for r in rows}


def Ci(d):
    """Mean of the paired differences d with its 95 % bootstrap CI (the
    package's own PairedDifference, as the study reports use)."""
    d = np.asarray(d, dtype=float)
    if not len(d):
        return "n/a"
    e = PairedDifference(d, np.zeros_like(d))
    return f"{e.value:+.3f} [{e.low:+.3f}, {e.high:+.3f}]"


def Flags(rows, column):
    return np.array([r[column] == "True" for r in rows], float)


def Compare(label, new, old, columns):
    keys = sorted(set(new) & set(old))
    n, o = [new[k] for k in keys], [old[k] for k in keys]
    line = f"{label} (n={len(keys)})"
    for c in columns:
        x, y = Flags(o, c), Flags(n, c)
        line += f" | {c} {int(x.sum())}->{int(y.sum())} {Ci(y - x)}"
    if keys:
        gap = [min(float(r["min_human_gap"]) for r in rows) for rows in (o, n)]
        line += f" | smallest gap {gap[0] * 1e3:.0f}->{gap[1] * 1e3:.0f} mm"
    print(line)


CONTACT = ["success", "collision", "robot_closing_contact", "wall_collision"]
METHODS = ("SM2ITH", "CVMM", "React")
print("== Ridgeback-UR10 doorway, SM2ITH: multipliers undamped vs damped")
for variant in ("paper", "safe"):
    for people in ("instructed", "orca"):
        match = dict(variant=variant, people=people)
        new = Keyed(Rows(HERE / "ridgeback_undamped.csv", **match), "humans", "seed")
        old = Keyed(Rows(HERE / "ridgeback_default.csv", **match), "humans", "seed")
        Compare(f"{variant}/{people}", new, old, CONTACT)

new = Keyed(
    Rows(HERE / "ridgeback_undamped.csv"), "variant", "people", "humans", "seed"
)
old = Keyed(Rows(HERE / "ridgeback_default.csv"), "variant", "people", "humans", "seed")
Compare("pooled", new, old, CONTACT)

print("== Stretch 3 doorway, safe, instructed: SM2ITH variants vs 5d9d1e4")


def ByMethod(path, methods):
    """The `safe` instructed rows of a study CSV, per method, by (humans,
    seed)."""
    rows = Rows(path, variant="safe", people="instructed")
    return {
        m: Keyed([r for r in rows if r["method"] == m], "humans", "seed")
        for m in methods
    }


ref = ByMethod(EXPERIMENTS / "doorway-30-5d9d1e4" / "doorway.csv", METHODS)
ref_rec = ByMethod(EXPERIMENTS / "recovery-b399eda" / "doorway.csv", METHODS[1:])
undamped = Keyed(
    Rows(EXPERIMENTS / "proximal-6b4b50a" / "instructed_multipliers_undamped.csv"),
    "humans",
    "seed",
)
undamped_recovery = Keyed(Rows(HERE / "undamped_recovery.csv"), "humans", "seed")
with_recovery = {**ref, **ref_rec, "SM2ITH undamped + recovery": undamped_recovery}
variants = [
    ("robot_share 0.25", HERE / "share_0.25.csv", ref),
    ("robot_share 0", HERE / "share_0.csv", ref),
    # CVMM and React with the recovery too (b399eda); SM2ITH: 5d9d1e4's.
    ("undamped + recovery", HERE / "undamped_recovery.csv", {**ref, **ref_rec}),
    # The recovery alone (multipliers damped, the paper's share).
    ("recovery alone", HERE / "recovery_alone.csv", {**ref, **ref_rec}),
    (
        "robot_share 0 + undamped + recovery",
        HERE / "share_0_undamped_recovery.csv",
        with_recovery,
    ),
    (
        "reciprocity + undamped + recovery",
        HERE / "reciprocity_undamped_recovery.csv",
        with_recovery,
    ),
    (
        "reciprocity (max_share 0.5) + undamped + recovery",
        HERE / "reciprocity_capped_undamped_recovery.csv",
        with_recovery,
    ),
]
for label, path, against in variants:
    new = Keyed(Rows(path), "humans", "seed")
    for h in sorted({k[0] for k in new}):
        cell = {k: r for k, r in new.items() if k[0] == h}
        arrivals = int(Flags(cell.values(), "success").sum())
        print(f"-- {label}, {h} people: arrivals {arrivals} of {len(cell)}")
        for m, old in against.items():
            Compare(f"   vs {m}", cell, old, ["success"])
        Compare("   vs SM2ITH undamped", cell, undamped, ["success", "collision"])
    if len({k[0] for k in new}) > 1:
        print(f"-- {label}, pooled over the people counts run")
        for m, old in against.items():
            Compare(f"   vs {m}", new, old, ["success"])

print("== Stretch 3 doorway, safe, ORCA people, 3 people: SM2ITH undamped + recovery")
orca = Keyed(Rows(HERE / "orca_undamped_recovery.csv"), "humans", "seed")
ref_orca = Keyed(
    Rows(
        EXPERIMENTS / "doorway-30-d1bef7f" / "doorway.csv",
        variant="safe",
        people="orca",
        method="SM2ITH",
    ),
    "humans",
    "seed",
)
Compare("undamped + recovery vs default (d1bef7f)", orca, ref_orca, CONTACT)
for label, name in [
    ("reciprocity", "orca_reciprocity_undamped_recovery.csv"),
    ("robot_share 0", "orca_share_0_undamped_recovery.csv"),
]:
    new = Keyed(Rows(HERE / name), "humans", "seed")
    if new:
        Compare(f"{label} + undamped + recovery vs without", new, orca, CONTACT)

print("== Stretch 3 head-on (adversarial) study, SM2ITH: robot_share 0 vs 0.5")
headon = ["variant", "people", "seed"]
share0 = Keyed(Rows(HERE / "headon_share_0_undamped.csv"), *headon)
half = Keyed(
    Rows(EXPERIMENTS / "proximal-6b4b50a" / "adversarial_multipliers_undamped.csv"),
    *headon,
)
Compare("both undamped, all variants and people", share0, half, CONTACT)
keys = sorted(set(share0) & set(half))
for column in ("progress_share", "base_retreat", "time_to_goal"):
    pairs = np.array([[float(half[k][column]), float(share0[k][column])] for k in keys])
    pairs = pairs[np.all(np.isfinite(pairs), axis=1)]
    print(f"   {column} (n={len(pairs)}): {Ci(pairs[:, 1] - pairs[:, 0])}")

print("== Stretch 3 doorway, safe, 3 people: safety.inside_barrier exit")
for people, name, against in [
    (
        "orca",
        "orca_exit_share_0_undamped_recovery.csv",
        "orca_share_0_undamped_recovery.csv",
    ),
    (
        "instructed",
        "exit_share_0_undamped_recovery.csv",
        "share_0_undamped_recovery.csv",
    ),
]:
    new = Keyed(Rows(HERE / name), "humans", "seed")
    old = Keyed(Rows(HERE / against, humans="3"), "humans", "seed")
    Compare(
        f"{people}: exit vs decay (both share 0 + undamped + recovery)",
        new,
        old,
        CONTACT,
    )

print("== Banner/cup (Stretch 3, ORCA and instructed people, both variants, 10 seeds)")
banner = ["scenario", "variant", "people", "seed"]
ref_banner = Keyed(
    Rows(EXPERIMENTS / "rerun-c48edcd" / "banner_cup.csv", method="SM2ITH"), *banner
)
for label, name in [
    ("robot_share 0 + undamped + recovery", "banner_cup_share_0_undamped_recovery.csv"),
    ("undamped + recovery", "banner_cup_undamped_recovery.csv"),
]:
    new = Keyed(Rows(HERE / name), *banner)
    for variant in ("paper", "safe"):
        for people in ("orca", "instructed"):
            cell = {k: r for k, r in new.items() if k[1:3] == (variant, people)}
            if cell:
                Compare(
                    f"{label} vs default, {variant}/{people}", cell, ref_banner, CONTACT
                )
    keys = sorted(set(new) & set(ref_banner))
    for column in ("time_to_goal", "ee_error_mean"):
        d = [float(new[k][column]) - float(ref_banner[k][column]) for k in keys]
        print(f"   {label}, {column} (n={len(keys)}): {Ci(d)}")

print("== Pick-and-place (both robots, both variants, 10 seeds): undamped + recovery")
ref_pnp = Keyed(
    Rows(EXPERIMENTS / "rerun-c48edcd" / "pick_and_place.csv", method="SM2ITH"),
    *banner,
)
pnp = Keyed(Rows(HERE / "pick_and_place_undamped_recovery.csv"), *banner)
for people in ("orca", "instructed"):
    new = {k: r for k, r in pnp.items() if k[2] == people}
    for variant in ("paper", "safe"):
        cell = {k: r for k, r in new.items() if k[1] == variant}
        Compare(f"vs default, {variant}/{people}", cell, ref_pnp, CONTACT)
    Compare(f"vs default, {people} pooled", new, ref_pnp, CONTACT)
    keys = sorted(set(new) & set(ref_pnp))
    for column in ("time_to_goal", "ee_error_mean", "freezing_time"):
        pairs = [[float(ref_pnp[k][column]), float(new[k][column])] for k in keys]
        pairs = np.array(pairs)
        pairs = pairs[np.all(np.isfinite(pairs), axis=1)]
        print(f"   {people} {column} (n={len(pairs)}): {Ci(pairs[:, 1] - pairs[:, 0])}")
