"""The Stretch 3 doorway with ORCA people, `safe`, 30 seeds per count:
every method's default runs, and SM²ITH with both options of this
directory's overtaking study (``prediction.overtaking`` with wait and
without the guard for overtakers, and ``safety.guard_gamma: 1``), paired
on (count, seed): arrivals, runs with contact, and of those the runs in
which the robot closed in on the person.

    sm2ith experiment doorway --runs 30 --variant safe --people orca \\
        --only doorway_stretch3 --jobs 2 \\
        --out docs/experiments/doorway-30-2026-11-28/overtaking/orca30-default
    sm2ith experiment doorway --runs 30 --variant safe --people orca \\
        --only doorway_stretch3 --methods SM2ITH --jobs 2 \\
        --out docs/experiments/doorway-30-2026-11-28/overtaking/orca30-options \\
        --scenario_text '{safety: {guard_gamma: 1.0}, prediction: {overtaking:
            {enabled: true, wait: true, guard: false}}}'
    python docs/experiments/doorway-30-2026-11-28/orca30.py

``orca30-guarded``: the same with ``guard: true`` (overtakers kept in the
guard, whose rows then ask only h ≥ 0).

Output: orca30.txt.
"""

from pathlib import Path

from sm2ith_drake.experiments.campaign import ReadRows
from sm2ith_drake.experiments.statistics import PairedDifference

HERE = Path(__file__).resolve().parent / "overtaking"
METHODS = ("SM2ITH", "CVMM", "React")
COUNTS = (1, 2, 3, 5)
# The options' runs (directories under overtaking/) and what they are.
RUNS = (
    ("orca30-options", "overtaking (wait, guard false) and guard_gamma 1"),
    ("orca30-wait-noguard", "overtaking (wait, guard false) without guard_gamma"),
    (
        "orca30-keep90",
        "overtaking (wait, guard false, keep_angle 90) and guard_gamma 1",
    ),
    (
        "orca30-keep90-guarded",
        "the defaults of 469abf3 with the overtakers kept in the guard",
    ),
    (
        "orca30-guarded",
        "overtaking (wait, overtakers kept in the guard) and guard_gamma 1",
    ),
)


def CI(a, b):
    e = PairedDifference(a, b)
    return f"{e.value:+.2f} [{e.low:+.2f}, {e.high:+.2f}]"


def Column(rows, keys, field, method=None):
    """0/1 per (count, seed) key: ``field`` is True in ``rows`` (keyed by
    (count, method, seed) when ``method`` is given)."""
    return [
        float(rows[k if method is None else (k[0], method, k[1])][field] is True)
        for k in keys
    ]


def main():
    default = {
        (r["humans"], r["method"], r["seed"]): r
        for r in ReadRows(HERE / "orca30-default" / "doorway.csv")
    }
    lines = []
    for name, what in RUNS:
        path = HERE / name / "doorway.csv"
        if path.exists():
            options = {(r["humans"], r["seed"]): r for r in ReadRows(path)}
            lines += Compare(options, default, what)
    text = "\n".join(lines)
    print(text)
    (HERE.parent / "orca30.txt").write_text(text + "\n")


def Compare(options, default, what):
    """The lines of one option's runs against every method's default."""
    lines = [
        f"Stretch 3 doorway, ORCA people, safe, 30 seeds per count: SM2ITH with "
        f"{what} against each method's default (arrivals; runs with contact; "
        "with the robot closing in); paired differences [95 % CI]"
    ]
    for counts in (COUNTS, *((c,) for c in COUNTS)):
        keys = sorted(k for k in options if k[0] in counts)

        ok, contact = (
            Column(options, keys, "success"),
            Column(options, keys, "collision"),
        )
        closing = Column(options, keys, "robot_closing_contact")
        label = "pooled" if len(counts) > 1 else f"{counts[0]} people"
        text = (
            f"  {label:9s} options: {int(sum(ok))}/{len(keys)}, contact "
            f"{int(sum(contact))}, closing {int(sum(closing))}"
        )
        for m in METHODS:
            their_ok = Column(default, keys, "success", m)
            their_contact = Column(default, keys, "collision", m)
            their_closing = Column(default, keys, "robot_closing_contact", m)
            text += (
                f"\n    {m:6s} {int(sum(their_ok)):3d} ({CI(ok, their_ok)}), contact "
                f"{int(sum(their_contact)):3d} ({CI(contact, their_contact)}), "
                f"closing {int(sum(their_closing)):3d} ({CI(closing, their_closing)})"
            )
        lines.append(text)
    return lines


if __name__ == "__main__":
    main()
