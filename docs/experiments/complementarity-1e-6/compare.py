"""SM²ITH's `safe` runs among ORCA people with the complementarity relaxation
ε = 1e-6 against the shipped 1e-5 (``../final-19b15d2``), run for run: runs
with contact, with the robot closing in, arrivals and the deepest contact
per robot (README, Contact in the `safe` variant).

    D=docs/experiments/complementarity-1e-6
    T="{prediction: {complementarity_relaxation: 1e-6}}"
    sm2ith experiment doorway --variant safe --people orca --methods SM2ITH \\
        --jobs 2 --out $D --scenario_text "$T"
    sm2ith experiment pick_and_place --variant safe --people orca \\
        --methods SM2ITH --jobs 2 --out $D --scenario_text "$T"
    python $D/compare.py > $D/compare.txt
"""

from pathlib import Path

from sm2ith_drake.experiments.campaign import ReadRows

HERE = Path(__file__).resolve().parent
OLD = HERE.parent / "final-19b15d2"

for study in ("doorway", "pick_and_place"):
    new = {r["run_id"]: r for r in ReadRows(HERE / f"{study}.csv")}
    old = {r["run_id"]: r for r in ReadRows(OLD / f"{study}.csv")}
    for robot in ("stretch3", "ridgeback_ur10"):
        keys = [k for k in new if k in old and new[k]["robot"] == robot]

        def Count(rows, key, keys=keys):
            return sum(rows[k][key] is True for k in keys)

        deepest = [min(rows[k]["min_human_gap"] for k in keys) for rows in (new, old)]
        print(
            f"{study} {robot}: {len(keys)} runs; with contact {Count(new, 'collision')}"
            f" (1e-5: {Count(old, 'collision')}), the robot closing in "
            f"{Count(new, 'robot_closing_contact')} "
            f"({Count(old, 'robot_closing_contact')}), arrivals "
            f"{Count(new, 'success')} ({Count(old, 'success')}), smallest gap "
            f"{deepest[0] * 1e3:.0f} mm ({deepest[1] * 1e3:.0f} mm)"
        )
