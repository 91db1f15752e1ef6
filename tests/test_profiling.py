"""The phase profiler (control/profiling.py) and ``sm2ith bench --profile``.

Speed is measured, not asserted: these tests check what is recorded and that
the accounting adds up, never how long anything took.
"""

import json
import time

import pytest

from sm2ith_drake.cli.main import main
from sm2ith_drake.control.profiling import OTHER, PROFILER, STEP, Profiler
from sm2ith_drake.run.bench import RunBenchmark

# The phases a control step with the ORCA-KKT predictor passes through.
EXPECTED_PHASES = [
    "predictor",
    "predictor_forward_sim",
    "restore_forward_sim",
    "orca_lines",
    "human_qps",
    "orca_line_derivatives",
    "kinematics",
    "control_step",
    "warm_start",
    "linearize:dynamics",
    "linearize:orca_kkt_equalities",
    "linearize:orca_kkt_inequalities",
    "linearize:dt_cbf",
    "qp_assembly",
]
# The stage QPs' phases, by the QP solver the benchmark ran with (auto is
# HPIPM for these small QPs where it is installed).
QP_PHASES = {
    "piqp": ["piqp", "piqp_setup", "piqp_solve", "piqp_kkt_factor", "piqp_kkt_solve"],
    "auto": ["hpipm", "hpipm_ipm"],
}


@pytest.fixture(autouse=True)
def _restore_profiler():
    enabled = PROFILER.enabled
    yield
    PROFILER.enabled = enabled
    PROFILER.Reset()


def test_disabled_profiler_is_a_no_op():
    p = Profiler()
    assert not p.enabled
    calls = []

    @p.Timed("f")
    def f(x):
        calls.append(x)
        return 2 * x

    p.BeginStep()
    with p.Phase("a"), p.Phase("b", "detail"):
        assert f(3) == 6
    p.EndStep()
    assert calls == [3]
    assert p.steps == [] and not p.outside and p.Summary() == {}
    # One shared do-nothing object: nothing is allocated per phase.
    assert p.Phase("a") is p.Phase("b")


def test_nested_phases_are_charged_exclusive_time():
    p = Profiler()
    p.Enable()

    @p.Timed("inner")
    def inner():
        return sum(range(1000))

    with p.Phase("setup"):
        inner()  # outside any step: kept apart
    for _ in range(3):
        p.BeginStep()
        with p.Phase("outer"):
            inner()
            with p.Phase("linearize", "dynamics"):
                inner()
        p.EndStep()
    assert set(p.outside) == {"setup", "inner"}
    assert len(p.steps) == 3
    for wall, exclusive, inclusive, calls in p.steps:
        assert set(exclusive) == {"outer", "inner", "linearize:dynamics"}
        assert calls == {"outer": 1, "inner": 2, "linearize:dynamics": 1}
        # A parent's inclusive time is the exclusive time of it and of every
        # phase nested in it (here: all of the step's phases).
        assert inclusive["outer"] == pytest.approx(sum(exclusive.values()), rel=1e-9)
        assert inclusive["linearize:dynamics"] >= exclusive["linearize:dynamics"]
        assert all(t >= 0 for t in exclusive.values())
        assert sum(exclusive.values()) <= wall
    summary = p.Summary()
    assert list(summary)[0] == STEP and list(summary)[-1] == OTHER
    assert summary[OTHER] >= 0
    assert p.CallsPerStep()["inner"] == 2


def test_recorded_time_is_taken_from_the_open_phase():
    p = Profiler()
    p.Enable()
    p.Record("solver_timer", 1.0)  # no open phase: ignored
    p.BeginStep()
    with p.Phase("solve"):
        time.sleep(0.02)
        p.Record("factor", 0.015)  # what a solver's own timer reported
    p.EndStep()
    _, exclusive, inclusive, calls = p.steps[0]
    assert exclusive["factor"] == pytest.approx(0.015)
    assert inclusive["solve"] >= 0.02
    assert exclusive["solve"] == pytest.approx(inclusive["solve"] - 0.015)
    assert calls["factor"] == 1
    assert "solver_timer" not in p.outside


@pytest.mark.parametrize("qp_solver", ["auto", "piqp"])
def test_bench_profile_has_the_phases_and_adds_up(qp_solver):
    text = f"{{controller: {{qp_solver: {qp_solver}}}}}"
    r = RunBenchmark(
        robot="stretch3", humans=1, steps=5, profile=True, scenario_text=text
    )
    assert not PROFILER.enabled  # restored after the run
    profile = r["profile"]
    expected = EXPECTED_PHASES + QP_PHASES[r["qp_solver"]]
    missing = [n for n in expected if n not in profile]
    assert not missing, f"phases not recorded: {missing}"
    assert any(n.startswith("linearize:task:") for n in profile)
    assert set(r["profile_inclusive"]) == set(profile) - {STEP, OTHER}
    # One profiled step per control instant, each instant one control step
    # with the predictor's prediction in it.
    assert len(PROFILER.steps) == 6  # instants 0 … 5
    for wall, exclusive, _, calls in PROFILER.steps:
        assert calls["control_step"] == 1 and calls["predictor"] == 1
        assert sum(exclusive.values()) <= wall
    assert "control_step" not in PROFILER.outside
    # The controller's step is part of the instant it is timed in.
    assert r["profile_inclusive"]["control_step"] <= profile[STEP]
    for key in ("p99_ms", "setup_ms", "first_step_ms", "instant_median_ms"):
        assert r[key] > 0
    assert r["median_ms"] <= r["p99_ms"] <= r["max_ms"]


def test_bench_without_profile_records_nothing():
    r = RunBenchmark(robot="stretch3", humans=0, steps=3)
    assert "profile" not in r
    assert PROFILER.steps == [] and not PROFILER.outside
    assert r["setup_ms"] > 0 and r["p99_ms"] > 0


def test_bench_cli_prints_and_writes_the_profile(tmp_path, capsys):
    out = tmp_path / "bench.json"
    argv = ["bench", "--robot", "stretch3", "--humans", "1", "--steps", "2"]
    assert main(argv + ["--profile", "--json", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "p99" in printed and "setup" in printed
    data = json.loads(out.read_text())
    assert QP_PHASES[data["qp_solver"]][-1] in printed and OTHER in printed
    assert STEP in data["profile"] and "setup_ms" in data and "p99_ms" in data


def test_bench_cli_repeats_in_rounds_and_prints_the_spread(tmp_path, capsys):
    out = tmp_path / "bench.json"
    argv = ["bench", "--robot", "all", "--humans", "1", "--steps", "2"]
    assert main(argv + ["--repeat", "2", "--json", str(out)]) == 0
    printed = capsys.readouterr().out
    data = json.loads(out.read_text())
    assert [(r["robot"], r["run"]) for r in data] == [
        ("ridgeback_ur10", 1),
        ("stretch3", 1),
        ("ridgeback_ur10", 2),
        ("stretch3", 2),
    ]
    for robot in ("ridgeback_ur10", "stretch3"):
        runs = [r for r in data if r["robot"] == robot]
        low = min(r["median_ms"] for r in runs)
        high = max(r["median_ms"] for r in runs)
        line = next(
            x
            for x in printed.splitlines()
            if x.startswith(f"{robot} ") and "over 2 runs" in x
        )
        assert f"median {low:.1f}–{high:.1f} ms" in line
        assert "the same plans" in line  # the runs are deterministic
    assert main(["bench", "--repeat", "0"]) == 2


def test_bench_counts_the_steps_the_qp_iteration_budget_cut():
    """``solved_through``: every step of a budget that only the exempt
    first stage fits has its lower stage left unoptimized (no failure, no
    fallback); without a budget, none."""
    text = "{controller: {qp_solver: piqp, qp_iteration_budget: %d}}"
    cut = RunBenchmark(robot="stretch3", humans=1, steps=3, scenario_text=text % 1)
    assert cut["solved_through"] == cut["steps"] == 3
    assert cut["solver_failures"] == 0 and cut["fallbacks"] == 0
    whole = RunBenchmark(robot="stretch3", humans=1, steps=3, scenario_text=text % 0)
    assert whole["solved_through"] == 0
    assert whole["mean_iterations"] > cut["mean_iterations"]
