"""Two levers measured on the final controller where SM²ITH falls behind
(Stretch 3, instructed people, `safe`, 2 and 3 people, 30 seeds each,
SM²ITH only), paired with this directory's runs of the default:

- ``pm``: ``{controller: {rti_proximal_multipliers: false}}``;
- ``rec``: ``{controller: {recovery: {enabled: true}}}`` (SM²ITH only here;
  it is every method's option);
- ``pm_rec``: both.

    sm2ith experiment doorway --runs 30 --variant safe --people instructed \\
        --methods SM2ITH --only doorway_stretch3_2h --jobs 2 \\
        --out docs/experiments/doorway-30-2026-11-28/levers/pm \\
        --scenario_text '{controller: {rti_proximal_multipliers: false}}'
    (and _3h; and rec)
    python docs/experiments/doorway-30-2026-11-28/levers.py
"""

from pathlib import Path

from sm2ith_drake.experiments.campaign import ReadRows
from sm2ith_drake.experiments.statistics import PairedDifference

HERE = Path(__file__).resolve().parent
LEVERS = ("pm", "rec", "pm_rec")
COUNTS = (2, 3)


def Outcome(rows, method, key="success"):
    return {
        (r["humans"], r["seed"]): r
        for r in rows
        if (r["robot"], r["people"], r["method"], r["variant"])
        == ("stretch3", "instructed", method, "safe")
    }


def _Diff(a, b, keys):
    e = PairedDifference(
        [float(a[k]["success"] is True) for k in keys],
        [float(b[k]["success"] is True) for k in keys],
    )
    return f"{e.value:+.2f} [{e.low:+.2f}, {e.high:+.2f}]"


def main():
    base_rows = ReadRows(HERE / "doorway.csv")
    base = {m: Outcome(base_rows, m) for m in ("SM2ITH", "CVMM", "React")}
    for lever in LEVERS:
        path = HERE / "levers" / lever / "doorway.csv"
        if not path.exists():
            continue
        s = Outcome(ReadRows(path), "SM2ITH")
        for count in (None, *COUNTS):
            keys = sorted(
                k
                for k in s
                if (count is None or k[0] == count)
                and all(k in b for b in base.values())
            )
            if not keys:
                continue
            got = sum(s[k]["success"] is True for k in keys)
            was = sum(base["SM2ITH"][k]["success"] is True for k in keys)
            contacts = sum(s[k]["collision"] is True for k in keys)
            name = "2+3 people" if count is None else f"{count} people"
            print(
                f"{lever:4s} {name:10s} SM²ITH {got}/{len(keys)} (default {was}), "
                f"contacts {contacts}; − default {_Diff(s, base['SM2ITH'], keys)}  "
                f"− CVMM {_Diff(s, base['CVMM'], keys)}  "
                f"− React {_Diff(s, base['React'], keys)}"
            )


if __name__ == "__main__":
    main()
