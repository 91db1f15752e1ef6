"""Scenario loading and the CLI's handling of bad input."""

import subprocess
import sys

import pytest

from sm2ith_drake.resources import GetDiagramsDir
from sm2ith_drake.scenario import ScenarioError
from sm2ith_drake.scenario_loader import LoadScenario, ScenarioNames

CONFLICT = str(GetDiagramsDir() / "conflict.scenarios.yaml")


def test_every_shipped_scenario_loads():
    files = sorted(GetDiagramsDir().glob("*.scenarios.yaml"))
    assert len(files) >= 3
    for path in files:
        names = ScenarioNames(path)
        assert names, path
        for name in names:
            scenario = LoadScenario(filename=path, scenario_name=name)
            assert scenario.tasks


def test_unknown_key_is_named():
    with pytest.raises(ScenarioError, match="controler"):
        LoadScenario(
            filename=CONFLICT,
            scenario_name="minimal",
            scenario_text="{controler: {horizon: 3}}",
        )


def test_override_changes_one_field():
    base = LoadScenario(filename=CONFLICT, scenario_name="conflict_ee_over_base")
    changed = LoadScenario(
        filename=CONFLICT,
        scenario_name="conflict_ee_over_base",
        scenario_text="{controller: {horizon: 7}}",
    )
    assert base.controller.horizon == 10
    assert changed.controller.horizon == 7
    assert changed.controller.time_step == base.controller.time_step
    assert [t.target for t in changed.tasks] == [t.target for t in base.tasks]


def test_bad_values_rejected():
    with pytest.raises(ScenarioError, match="method"):
        LoadScenario(
            filename=CONFLICT,
            scenario_name="minimal",
            scenario_text="{controller: {method: best}}",
        )
    with pytest.raises(ScenarioError, match="task kind"):
        LoadScenario(
            filename=CONFLICT,
            scenario_name="minimal",
            scenario_text="{tasks: [{kind: dance}]}",
        )
    with pytest.raises(ScenarioError, match="prediction.kkt_steps must be ≥ 0"):
        LoadScenario(
            filename=CONFLICT,
            scenario_name="minimal",
            scenario_text="{prediction: {kkt_steps: -1}}",
        )


def _cli(*args, cwd=None):
    return subprocess.run(
        [sys.executable, "-m", "sm2ith_drake.cli", *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=120,
    )


@pytest.mark.parametrize(
    "args, message",
    [
        (["run", "no_such_file.scenarios.yaml", "--scenario", "x"], "not found"),
        (["run", CONFLICT, "--scenario", "nope"], "valid names: conflict_ee_over_base"),
        (
            ["run", CONFLICT, "--scenario", "minimal", "--scenario_text", "{a: [}"],
            "minimal",
        ),
    ],
)
def test_cli_user_errors_are_one_line(args, message, tmp_path):
    result = _cli(*args, "--no-meshcat", cwd=tmp_path)
    assert result.returncode == 2
    assert "Traceback" not in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    assert message in result.stderr


def test_cli_malformed_yaml_file(tmp_path):
    bad = tmp_path / "bad.scenarios.yaml"
    bad.write_text("a: [1, 2\nb: {")
    result = _cli("run", str(bad), "--scenario", "a", "--no-meshcat", cwd=tmp_path)
    assert result.returncode == 2
    assert "malformed YAML" in result.stderr
    assert "Traceback" not in result.stderr


def _AllScenarios():
    return [
        (path.name, name)
        for path in sorted(GetDiagramsDir().glob("*.scenarios.yaml"))
        for name in ScenarioNames(path)
    ]


@pytest.mark.parametrize("filename,name", _AllScenarios())
def test_every_shipped_scenario_runs_closed_loop(filename, name):
    """A short closed-loop smoke test of every named scenario."""
    import numpy as np

    from sm2ith_drake.run.simulation import RunSimulation

    scenario = LoadScenario(filename=GetDiagramsDir() / filename, scenario_name=name)
    result = RunSimulation(scenario, duration=1.5)
    metrics = result.metrics
    assert result.log.counters.steps >= 7
    assert metrics["limit_violations"] == 0
    assert metrics["solver_failures"] == 0
    robot = result.diagram.GetSubsystemByName("controller").controller.robot
    states = np.array(result.log.states)
    assert np.all(np.isfinite(states))
    if robot.base_kind == "differential":
        # The base never moves sideways (G(q) enforced in closed loop).
        times = np.array(result.log.times)
        n = robot.num_positions
        for x in states:
            qdot = robot.G(x[:n]) @ x[n:]
            assert abs(-np.sin(x[2]) * qdot[0] + np.cos(x[2]) * qdot[1]) < 1e-12
        step = np.diff(states[:, :2], axis=0)
        heading = states[:-1, 2] + 0.5 * np.diff(states[:, 2])
        sideways = -np.sin(heading) * step[:, 0] + np.cos(heading) * step[:, 1]
        assert np.max(np.abs(sideways)) < 1e-3 * max(1.0, np.diff(times).max())


def test_bench_writes_the_documented_json(tmp_path):
    """`sm2ith bench` with people writes every documented key (timing is a
    measurement, not asserted)."""
    import json

    out = tmp_path / "bench.json"
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "sm2ith_drake.cli",
            "bench",
            "--robot",
            "stretch3",
            "--humans",
            "1",
            "--predictor",
            "cvmm",
            "--steps",
            "5",
            "--scenario_text",
            "{prediction: {max_neighbors: 0}}",
            "--json",
            str(out),
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    data = json.loads(out.read_text())
    for key in (
        "median_ms",
        "p95_ms",
        "max_ms",
        "mean_iterations",
        "solver_failures",
        "fallbacks",
        "steps",
        "robot",
        "humans",
        "predictor",
        "mean_passes",
        "max_neighbors",
        "kkt_steps",
    ):
        assert key in data, key
    assert data["steps"] == 5 and data["humans"] == 1 and data["predictor"] == "cvmm"
    assert data["p95_ms"] >= data["median_ms"] > 0
    assert data["max_neighbors"] == 0


def test_bench_rejects_a_bad_scenario_text():
    from sm2ith_drake.cli import main

    assert main(["bench", "--steps", "1", "--scenario_text", "{nope: 1}"]) == 2
