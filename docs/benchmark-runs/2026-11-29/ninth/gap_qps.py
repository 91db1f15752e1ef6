"""PIQP's duality-gap tolerance on dumped 10-person stage QPs (README,
Benchmark, 2026-11-29, ninth session).

    python gap_qps.py DUMP.pkl... -- SETTINGS...

DUMP.pkl from ``../lazy-rows/qp_settings.py dump`` / ``hard``. Prints, for
each settings dict (over the shipped ones), the iterations in all QPs and
in those the shipped settings take more than 40 for, and how far the
solutions and objectives move on the QPs the shipped settings solve."""

import pickle
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent.parent / "lazy-rows"))
from qp_settings import Solve  # noqa: E402

split = sys.argv.index("--")
qps = [d for f in sys.argv[1:split] for d in pickle.load(open(f, "rb"))]
base = [Solve(d, {}) for d in qps]
base_iterations = np.array([r[2] for r in base])
solved = np.array([r[1] == "PIQP_SOLVED" for r in base])
hard = base_iterations > 40
print(
    f"shipped: {len(qps)} QPs, {base_iterations.sum()} iterations, "
    f"{hard.sum()} QPs over 40 with {base_iterations[hard].sum()}, "
    f"{sum(r[3] for r in base) * 1e3:.0f} ms, {len(qps) - solved.sum()} not solved"
)
for text in sys.argv[split + 1 :]:
    results = [Solve(d, eval(text)) for d in qps]  # noqa: S307 (a dict literal)
    iterations = np.array([r[2] for r in results])
    objective = np.array(
        [
            abs(r[4] - b[4]) / max(1.0, abs(b[4]))
            for r, b in zip(results, base, strict=True)
        ]
    )
    moved = np.array(
        [np.max(np.abs(r[0] - b[0])) for r, b in zip(results, base, strict=True)]
    )
    print(
        f"{text}: {iterations.sum()} iterations (median {np.median(iterations):.0f}, "
        f"max {iterations.max()}), the {hard.sum()} over 40: "
        f"{iterations[hard].sum()}, {sum(r[3] for r in results) * 1e3:.0f} ms, "
        f"{sum(r[1] != 'PIQP_SOLVED' for r in results)} not solved; on the "
        f"QPs solved before: objectives within {objective[solved].max():.1e} "
        f"rel., solutions moved by up to {moved[solved].max():.1e}"
    )
