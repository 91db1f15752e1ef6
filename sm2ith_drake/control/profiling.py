"""A phase profiler of the control step (``sm2ith bench --profile``).

``PROFILER`` is one module-level object. Off (the default) every
instrumented place costs one attribute test: ``PROFILER.Phase(name)``
returns a shared do-nothing context manager and ``@PROFILER.Timed(name)``
calls straight through. On, each phase's wall time is accumulated into the
open step:

- Phases nest. A phase is charged its *exclusive* time: its wall time minus
  that of the phases opened inside it. So the phases of a step never double
  count, and they add up to the step's wall time less the time spent outside
  every phase, which :meth:`Profiler.Summary` reports as ``other``
  (bookkeeping: Drake's event dispatch, the other systems' updates at the
  control instant, the code between the instrumented places).
- A step is whatever runs between :meth:`Profiler.BeginStep` and
  :meth:`Profiler.EndStep`. The benchmark (run/bench.py) delimits one step
  per control instant: it advances the simulator to the instant, then
  performs that instant's pending events inside Begin/EndStep, so the
  HumanPredictor's prediction (evaluated by the first update that reads it,
  at the same instant) and the controller's step fall into the same step.
  Phases recorded outside any step are kept apart (:attr:`outside`).

The summary is the median over steps of each phase's time per step (a phase
absent from a step counts 0 there). Medians of parts do not add up exactly
to the median of the whole; the per-step sums do.
"""

from __future__ import annotations

import functools
import time
from collections import defaultdict

import numpy as np

# Names a step's summary reports besides its phases.
STEP = "control_instant"
OTHER = "other/bookkeeping"


class _Off:
    """The phase of a disabled profiler: does nothing."""

    __slots__ = ()

    def __enter__(self):
        return None

    def __exit__(self, *exc):
        return False


_OFF = _Off()


class _Span:
    """One open phase of an enabled profiler."""

    __slots__ = ("profiler", "name", "start", "children")

    def __init__(self, profiler, name: str):
        self.profiler = profiler
        self.name = name

    def __enter__(self):
        self.children = 0.0
        self.profiler._stack.append(self)
        self.start = time.perf_counter()
        return None

    def __exit__(self, *exc):
        elapsed = time.perf_counter() - self.start
        profiler = self.profiler
        stack = profiler._stack
        stack.pop()
        if stack:
            stack[-1].children += elapsed
        if profiler._current is None:
            profiler.outside[self.name] += elapsed - self.children
        else:
            profiler._current[self.name] += elapsed - self.children
            profiler._inclusive[self.name] += elapsed
            profiler._calls[self.name] += 1
        return False


class Profiler:
    """Accumulates the exclusive wall time of named phases per step."""

    def __init__(self):
        self.enabled = False
        self.Reset()

    def Enable(self) -> None:
        self.enabled = True

    def Disable(self) -> None:
        self.enabled = False

    def Reset(self) -> None:
        """Forgets every step (the enabled flag is kept)."""
        self._stack: list[_Span] = []
        self._current: defaultdict | None = None
        self._inclusive: defaultdict = defaultdict(float)
        self._calls: defaultdict = defaultdict(int)
        self._start = 0.0
        # Per step: (wall time, {phase: exclusive s}, {phase: inclusive s},
        # {phase: calls}).
        self.steps: list[tuple[float, dict, dict, dict]] = []
        # Phase time recorded while no step was open.
        self.outside: defaultdict = defaultdict(float)

    def Phase(self, name: str, detail: str | None = None):
        """A context manager timing ``name`` (``name:detail`` if given; the
        detail is joined only when enabled)."""
        if not self.enabled:
            return _OFF
        return _Span(self, name if detail is None else f"{name}:{detail}")

    def Timed(self, name: str):
        """Decorator: the function's calls are the phase ``name``."""

        def decorate(function):
            @functools.wraps(function)
            def timed(*args, **kwargs):
                if not self.enabled:
                    return function(*args, **kwargs)
                with _Span(self, name):
                    return function(*args, **kwargs)

            return timed

        return decorate

    def Record(self, name: str, seconds: float) -> None:
        """Charges ``seconds`` that something else timed (a solver's own
        timers) inside the innermost open phase to the nested phase
        ``name``: the open phase's exclusive time shrinks by as much."""
        if not self.enabled or not self._stack:
            return
        seconds = max(0.0, float(seconds))
        self._stack[-1].children += seconds
        if self._current is None:
            self.outside[name] += seconds
        else:
            self._current[name] += seconds
            self._inclusive[name] += seconds
            self._calls[name] += 1

    def BeginStep(self) -> None:
        """Opens a step (closing one still open)."""
        if not self.enabled:
            return
        if self._current is not None:
            self.EndStep()
        self._current = defaultdict(float)
        self._inclusive = defaultdict(float)
        self._calls = defaultdict(int)
        self._start = time.perf_counter()

    def EndStep(self) -> None:
        """Closes the open step and stores it."""
        if not self.enabled or self._current is None:
            return
        wall = time.perf_counter() - self._start
        self.steps.append(
            (wall, dict(self._current), dict(self._inclusive), dict(self._calls))
        )
        self._current = None

    def Summary(self, steps: slice | None = None) -> dict:
        """{phase: median exclusive ms per step} over the stored steps
        (``steps`` selects some), with ``control_instant`` (the step's wall
        time) first and ``other/bookkeeping`` (the step's time outside every
        phase) last; phases by median, largest first."""
        return self._Medians(1, steps, with_totals=True)

    def InclusiveSummary(self, steps: slice | None = None) -> dict:
        """{phase: median inclusive ms per step} (a phase with the phases
        opened inside it), in :meth:`Summary`'s order."""
        inclusive = self._Medians(2, steps, with_totals=False)
        return {n: inclusive[n] for n in self.Summary(steps) if n in inclusive}

    def CallsPerStep(self, steps: slice | None = None) -> dict:
        """{phase: mean calls per step} over the stored steps."""
        chosen = self.steps if steps is None else self.steps[steps]
        total: defaultdict = defaultdict(int)
        for step in chosen:
            for name, count in step[3].items():
                total[name] += count
        return {n: c / max(1, len(chosen)) for n, c in total.items()}

    def _Medians(self, which: int, steps, *, with_totals: bool) -> dict:
        chosen = self.steps if steps is None else self.steps[steps]
        if not chosen:
            return {}
        names = sorted({n for step in chosen for n in step[which]})
        table = np.array([[step[which].get(n, 0.0) for n in names] for step in chosen])
        table = table.reshape(len(chosen), len(names))
        medians = np.median(table, axis=0) * 1e3
        order = np.argsort(-medians, kind="stable")
        phases = {names[i]: float(medians[i]) for i in order}
        if not with_totals:
            return phases
        wall = np.array([step[0] for step in chosen])
        out = {STEP: float(np.median(wall) * 1e3), **phases}
        out[OTHER] = float(np.median(wall - table.sum(axis=1)) * 1e3)
        return out


PROFILER = Profiler()
