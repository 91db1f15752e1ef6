"""The Stretch 3 doorway with instructed people, 30 seeds per person count:
SM²ITH with ``prediction.overtaking`` (a person walking toward the moving
robot from behind it is predicted to take all of the avoidance of it,
``share``; with ``wait``, also to wait behind it) against SM²ITH's, CVMM's
and React's default runs on the same seeds (this directory's
``doorway.csv``; CVMM and React do not read the option), paired on
(count, seed), per count and pooled, in each variant; the runs with
contact; and, with one person, SM²ITH's outcomes by where the person
starts (behind the robot, walking the same way, or oncoming).

    sm2ith experiment doorway --runs 30 --variant paper,safe --people instructed \\
        --only doorway_stretch3 --methods SM2ITH --jobs 2 \\
        --out docs/experiments/doorway-30-2026-11-28/overtaking/OPTION \\
        --scenario_text '{prediction: {overtaking: {enabled: true}}}'
    python docs/experiments/doorway-30-2026-11-28/overtaking.py

OPTION (the directory; its --scenario_text):

- ``share``: ``{prediction: {overtaking: {enabled: true}}}``;
- ``wait``: ``{prediction: {overtaking: {enabled: true, wait: true}}}``;
- ``wait-noguard``: ``{..., wait: true, guard: false}``, `safe` only
  (`paper` has no guard);
- ``wait-noguard-gamma1``: that and ``{safety: {guard_gamma: 1.0}}``,
  `safe` only;
- ``gamma1``: ``{safety: {guard_gamma: 1.0}}`` alone, `safe` only;
- ``wait-gamma1``: ``wait`` (overtakers kept in the guard) and
  ``guard_gamma: 1``, `safe` only;
- ``keep90``: ``wait-noguard-gamma1`` with ``keep_angle: 90`` (the rule
  keeps its overtakers while both angles stay within 90°), `safe` only:
  the defaults since 469abf3;
- ``default-469abf3``: the defaults of 469abf3 (no --scenario_text),
  `paper` only;
- ``keep90-guarded``: the defaults of 469abf3 with the overtakers kept in
  the guard (``{prediction: {overtaking: {guard: true}}}``), `safe` only.

``others`` and ``others-gamma1``: wait-noguard and wait-noguard-gamma1
with ORCA and social-force people (``--runs 10 --people
orca,social_force``), against the final re-run's runs on the same seeds
(``../final-2026-11-28/doorway.csv``); ``banner_cup``, ``pick_and_place``
(and ``-gamma1``): the same among ORCA people in those studies
(``sm2ith experiment STUDY --people orca --methods SM2ITH``) against the
final re-run. Output: overtaking.txt.
"""

from pathlib import Path

from sm2ith_drake.experiments.campaign import ReadRows
from sm2ith_drake.experiments.statistics import PairedDifference

HERE = Path(__file__).resolve().parent
OPTIONS = (
    "share",
    "wait",
    "wait-noguard",
    "wait-noguard-gamma1",
    "gamma1",
    "wait-gamma1",
    "keep90",
    "default-469abf3",
    "keep90-guarded",
)
METHODS = ("SM2ITH", "CVMM", "React")
COUNTS = (1, 2, 3, 5)


def Runs(path, people="instructed"):
    """(variant, count, method, seed) → row, Stretch 3, ``people``."""
    return {
        (r["variant"], r["humans"], r["method"], r["seed"]): r
        for r in ReadRows(path)
        if (r["robot"], r["people"]) == ("stretch3", people)
    }


def Ok(runs, key):
    return float(runs[key]["success"] is True)


def Compare(new, default, variant, counts):
    """One line: the option's arrivals against each method's default."""
    keys = sorted(
        (h, s) for (v, h, m, s) in new if v == variant and m == "SM2ITH" and h in counts
    )
    ours = [Ok(new, (variant, h, "SM2ITH", s)) for h, s in keys]
    contact = sum(new[(variant, h, "SM2ITH", s)]["collision"] is True for h, s in keys)
    label = "pooled" if len(counts) > 1 else f"{counts[0]} people"
    text = f"  {variant:5s} {label:9s} {int(sum(ours)):3d}/{len(keys)}"
    for m in METHODS:
        theirs = [Ok(default, (variant, h, m, s)) for h, s in keys]
        e = PairedDifference(ours, theirs)
        ci = f"{e.value:+.2f} [{e.low:+.2f}, {e.high:+.2f}]"
        text += f" | {m} {int(sum(theirs)):3d} ({ci})"
    return text + f" | runs with contact {contact}"


def ByStart(new, default, option):
    """SM²ITH's one-person runs in `safe` by where the person starts."""
    from sm2ith_drake.experiments.runs import LoadRunScenario, SpecFromRow
    from sm2ith_drake.experiments.studies import STUDIES

    out = []
    for where in ("behind", "oncoming"):
        seeds = []
        for (v, h, m, s), row in sorted(new.items()):
            if (v, h, m) != ("safe", 1, "SM2ITH"):
                continue
            person = LoadRunScenario(SpecFromRow(STUDIES["doorway"], row)).humans[0]
            if (person.start[1] < 0) == (where == "behind"):
                seeds.append(s)
        counts = {
            m: int(sum(Ok(default, ("safe", 1, m, s)) for s in seeds)) for m in METHODS
        }
        ours = int(sum(Ok(new, ("safe", 1, "SM2ITH", s)) for s in seeds))
        out.append(
            f"  {where:8s} {len(seeds):2d} runs: {option} {ours}, default SM2ITH "
            f"{counts['SM2ITH']}, CVMM {counts['CVMM']}, React {counts['React']}"
        )
    return out


def OtherStudy(study, path, option):
    """SM²ITH with the option (wait, guard false) among ORCA people in
    ``study`` against its final re-run runs on the same cells and seeds:
    success, runs with contact and those with the robot closing in."""
    final = HERE.parent / "final-2026-11-28" / f"{study}.csv"

    def Key(r):
        return (r["run_id"].split("/")[0], r["variant"], r["seed"])

    def Rows(p):
        return {
            Key(r): r
            for r in ReadRows(p)
            if (r["people"], r["method"]) == ("orca", "SM2ITH")
        }

    new, old = Rows(path), Rows(final)
    lines = [
        f"{study}, ORCA people, SM2ITH with {option} against the final "
        "re-run's runs (success; runs with contact; of them with the robot "
        "closing in)"
    ]
    for variant in sorted({k[1] for k in new}, reverse=True):
        keys = sorted(k for k in new if k[1] == variant and k in old)
        a = [float(new[k]["success"] is True) for k in keys]
        b = [float(old[k]["success"] is True) for k in keys]
        e = PairedDifference(a, b)
        counts = [
            (
                sum(d[k]["collision"] is True for k in keys),
                sum(d[k]["robot_closing_contact"] is True for k in keys),
            )
            for d in (new, old)
        ]
        lines.append(
            f"  {variant:5s} {len(keys)} runs: success {int(sum(a))} vs {int(sum(b))} "
            f"({e.value:+.2f} [{e.low:+.2f}, {e.high:+.2f}]); contact "
            f"{counts[0][0]} vs {counts[1][0]}, closing {counts[0][1]} vs "
            f"{counts[1][1]}"
        )
    return lines


def main():
    default = Runs(HERE / "doorway.csv")
    lines = []
    for option in OPTIONS:
        path = HERE / "overtaking" / option / "doorway.csv"
        if not path.exists():
            continue
        new = Runs(path)
        lines.append(
            f"{option}: SM2ITH with it (arrivals) against each method's default "
            "runs (arrivals, paired difference [95 % CI])"
        )
        for variant in sorted({k[0] for k in new}, reverse=True):
            for counts in (COUNTS, *((c,) for c in COUNTS)):
                lines.append(Compare(new, default, variant, counts))
        lines.append("  one person, safe, by where the person starts:")
        lines += ByStart(new, default, option)
    final = HERE.parent / "final-2026-11-28" / "doorway.csv"
    for suffix, option in (("", "wait-noguard"), ("-gamma1", "wait-noguard-gamma1")):
        others = HERE / "overtaking" / f"others{suffix}" / "doorway.csv"
        if not others.exists():
            continue
        for people in ("orca", "social_force"):
            lines.append(
                f"{option}, {people} people, 10 seeds per count: against the "
                "final re-run's runs (final-2026-11-28)"
            )
            new, old = Runs(others, people), Runs(final, people)
            for variant in sorted({k[0] for k in new}, reverse=True):
                for counts in (COUNTS, *((c,) for c in COUNTS)):
                    lines.append(Compare(new, old, variant, counts))
        for study in ("banner_cup", "pick_and_place"):
            path = HERE / "overtaking" / f"{study}{suffix}" / f"{study}.csv"
            if path.exists():
                lines += OtherStudy(study, path, option)
    text = "\n".join(lines)
    print(text)
    (HERE / "overtaking.txt").write_text(text + "\n")


if __name__ == "__main__":
    main()
