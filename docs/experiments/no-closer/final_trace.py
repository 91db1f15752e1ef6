"""The final re-run's trace module (docs/experiments/final-2026-11-28/trace.py:
Resimulate, ResimulateRun), loaded from its file for this directory's
scripts (its own name would otherwise be the standard library's
``trace``), and their ``--jobs`` option."""

import importlib.util
from pathlib import Path

_SPEC = importlib.util.spec_from_file_location(
    "final_trace", Path(__file__).parents[1] / "final-2026-11-28" / "trace.py"
)
TRACE = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(TRACE)


def JobsOption(argv, default=2):
    """(N of ``--jobs N`` in argv, or ``default``; argv without it)."""
    if "--jobs" not in argv:
        return default, list(argv)
    k = argv.index("--jobs")
    return int(argv[k + 1]), argv[:k] + argv[k + 2 :]
