"""Section V metrics on synthetic trajectories, and campaigns end to end."""

import csv
import dataclasses
import math
import subprocess
import sys

import numpy as np
import pytest

from sm2ith_drake.experiments.campaign import (
    COLUMNS,
    PlanRuns,
    ReadRows,
    RunCampaign,
    RunOne,
)
from sm2ith_drake.experiments.studies import STUDIES
from sm2ith_drake.robots import MobileManipulator
from sm2ith_drake.run.metrics import (
    INTIMATE_DISTANCE,
    CampaignRow,
    HumanMetrics,
    PathDeviation,
    PolylineDistances,
    Retreat,
)
from sm2ith_drake.scenario import PhaseConfig, Scenario, TaskConfig
from sm2ith_drake.systems.logger import RunLog


def test_path_deviation_against_hand_values():
    line = [[0.0, 0.0], [4.0, 0.0]]
    assert PathDeviation([[1.0, 0.1], [2.0, -0.1], [3.0, 0.1]], line) == (
        pytest.approx(0.1)
    )
    # Beyond the end of the path: the distance to the end point.
    assert PolylineDistances([[5.0, 0.0], [-3.0, 4.0]], line) == pytest.approx(
        [1.0, 5.0]
    )
    # An L-shaped path: the nearest leg counts.
    corner = [[0.0, 0.0], [2.0, 0.0], [2.0, 2.0]]
    assert PolylineDistances([[1.0, 0.5], [2.3, 1.0], [2.5, -0.5]], corner) == (
        pytest.approx([0.5, 0.3, math.hypot(0.5, 0.5)])
    )
    # A single-point reference.
    assert PathDeviation([[3.0, 4.0]], [[0.0, 0.0]]) == pytest.approx(5.0)


def test_retreat_against_hand_values():
    # Approaches to 1.0, backs off to 2.5, then reaches the goal: 1.5 m given
    # back.
    assert Retreat([3.0, 2.0, 1.0, 1.5, 2.5, 1.0, 0.0]) == pytest.approx(1.5)
    assert Retreat([3.0, 2.0, 1.0, 0.0]) == 0.0
    # A new phase (a new goal farther away) is not a retreat.
    d = [3.0, 2.0, 1.0, 5.0, 4.0, 4.5, 3.0]
    assert Retreat(d, [0, 0, 0, 1, 1, 1, 1]) == pytest.approx(0.5)
    assert Retreat(d) == pytest.approx(4.0)


@pytest.fixture(scope="module")
def stretch():
    return MobileManipulator("stretch3")


def _ArmOutLog(stretch, human_near_arm):
    """Ten samples 0.1 s apart of a Stretch 3 standing at the origin with its
    arm extended to its right (−y); a person stands at ``human_near_arm``
    for samples 3–6 and far away otherwise."""
    q = np.array([0.0, 0.0, 0.0, 0.76, 0.4, 0.0, 0.0])
    x = np.concatenate([q, np.zeros(stretch.num_velocities)])
    far = np.array([[6.0, 6.0]])
    log = RunLog()
    for i in range(10):
        log.times.append(0.1 * i)
        log.states.append(x)
        log.human_positions.append(np.array([human_near_arm]) if 3 <= i <= 6 else far)
    return log, q


def test_intimate_space_time_counts_an_arm_link(stretch):
    q = np.array([0.0, 0.0, 0.0, 0.76, 0.4, 0.0, 0.0])
    p_ee = stretch.CalcKinematics(q[None]).p_WE[0]
    # The gripper is well to the robot's right: 0.8 m from the base centre.
    assert p_ee[1] < -0.75
    # The person stands 0.35 m beyond the gripper, on its line: the base is
    # far outside the 0.45 m circle (base radius 0.17 m), the arm inside.
    person = [p_ee[0], p_ee[1] - 0.35]
    base_clearance = np.hypot(*person) - 0.17 - 0.12  # capsule ends at x=-0.12
    assert base_clearance > INTIMATE_DISTANCE
    log, _ = _ArmOutLog(stretch, person)
    metrics = HumanMetrics(log, stretch, [0.3])
    # Four samples (3, 4, 5, 6) of 0.1 s each.
    assert metrics["intimate_space_time"] == pytest.approx(0.4)
    assert metrics["collision_samples"] == 0
    # Distance to the nearest body is at most the distance to the EE point
    # and more than the gripper capsule's radius less.
    assert metrics["min_human_gap"] + 0.3 <= 0.35 + 1e-9
    assert metrics["min_human_gap"] + 0.3 >= 0.35 - 0.045 - 0.05

    # Move the person 0.6 m beyond the gripper: nobody is inside.
    log, _ = _ArmOutLog(stretch, [p_ee[0], p_ee[1] - 0.6])
    assert HumanMetrics(log, stretch, [0.3])["intimate_space_time"] == 0.0


def test_campaign_row_task_and_sequence_metrics(stretch):
    scenario = Scenario(
        tasks=[
            TaskConfig(kind="ee_position_in_base", target=[0.0, -0.5, 0.8]),
            TaskConfig(kind="base_position", target=[2.0, 0.0]),
        ],
        sequence=[PhaseConfig(name="a"), PhaseConfig(name="b")],
    )
    log = RunLog()
    log.times = [0.0, 0.5, 1.0, 1.5]
    log.states = [np.zeros(14)] * 4
    log.phases = [0, 0, 1, 1]
    log.task_errors = {
        "ee_position_in_base": [np.array([0.3, 0.4, 0.0])] + [np.zeros(3)] * 3,
        "base_position": [np.array([2.0, 0.0]), np.array([1.0, 0.0])]
        + [np.array([0.5, 0.0]), np.array([0.0, 0.0])],
    }
    done = {"phases_completed": 2, "sequence_time": 1.25, "fallbacks": 3}
    row = CampaignRow(log, stretch, scenario, done, [[0.0, 0.0], [2.0, 0.0]])
    assert row["ee_error_mean"] == pytest.approx(0.5 / 4)
    assert row["ee_error_max"] == pytest.approx(0.5)
    assert row["base_error_mean"] == pytest.approx(3.5 / 4)
    assert row["base_error_final"] == 0.0
    assert row["success"] is True and row["navigation_time"] == 1.25
    assert row["base_path_deviation"] == 0.0
    assert row["fallbacks"] == 3
    timeout = CampaignRow(log, stretch, scenario, {"phases_completed": 1}, None)
    assert timeout["success"] is False and math.isnan(timeout["navigation_time"])


def test_studies_follow_the_paper():
    pp = PlanRuns(STUDIES["pick_and_place"])
    assert len(pp) == 80  # 2 robots × 2 crowds × (10 + 5 + 5)
    assert {r.method for r in pp} == {"SM2ITH", "CVMM", "React"}
    assert len(PlanRuns(STUDIES["banner_cup"])) == 60
    assert len(PlanRuns(STUDIES["pick_and_place"], runs=1, only="stretch3_2h")) == 3


def _cli(*args, cwd):
    return subprocess.run(
        [sys.executable, "-m", "sm2ith_drake.cli", *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=600,
    )


def test_mini_campaign_end_to_end(tmp_path):
    out = tmp_path / "out"
    args = ["experiment", "adversarial", "--runs", "1", "--jobs", "2"]
    args += ["--duration", "3", "--out", str(out)]
    first = _cli(*args, cwd=tmp_path)
    assert first.returncode == 0, first.stderr[-2000:]
    with open(out / "adversarial.csv", newline="") as f:
        raw = list(csv.DictReader(f))
    assert len(raw) == 2 and list(raw[0]) == COLUMNS
    for row in raw:
        assert row["status"] == "ok", row["error"]
        for key in ("run_id", "scenario", "method", "seed", "min_human_gap"):
            assert row[key] not in ("", "nan"), key
        assert float(row["simulated_time"]) == pytest.approx(3.0, abs=0.06)
    png = (out / "adversarial.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000
    import matplotlib.image

    image = matplotlib.image.imread(out / "adversarial.png")
    assert image.shape[0] > 200 and image.shape[1] > 400
    assert np.ptp(image[..., :3]) > 0.5  # not a blank canvas
    report = (out / "adversarial_report.md").read_text()
    assert "| 1 |" in report and "SM2ITH" in report and "CVMM" in report

    # Resume: both runs are found and skipped; nothing is appended.
    again = _cli(*args, cwd=tmp_path)
    assert again.returncode == 0
    assert "2 skipped" in again.stdout
    assert len(ReadRows(out / "adversarial.csv")) == 2
    with open(out / "adversarial.csv") as f:
        assert len(f.readlines()) == 3

    # Replay a row (without Meshcat here), and a bad row.
    replay = _cli(
        "replay", str(out / "adversarial.csv"), "1", "--no-meshcat", cwd=tmp_path
    )
    assert replay.returncode == 0, replay.stderr[-2000:]
    assert "replaying adversarial_stretch3/" in replay.stdout
    bad = _cli("replay", str(out / "adversarial.csv"), "7", cwd=tmp_path)
    assert bad.returncode == 2 and "ROW must be" in bad.stderr


def test_same_seed_reproduces_the_metrics(tmp_path):
    spec = PlanRuns(STUDIES["pick_and_place"], runs=2, only="ridgeback_ur10_1h")[1]
    spec = dataclasses.replace(spec, duration=4.0)
    assert spec.seed == 1
    a, b = RunOne(spec, str(tmp_path)), RunOne(spec, str(tmp_path))
    other = RunOne(dataclasses.replace(spec, seed=0), str(tmp_path))
    timing = {"wall_time_s", "step_time_median_ms", "step_time_p95_ms"}
    timing |= {"step_time_max_ms"}
    assert a["status"] == b["status"] == "ok"
    for key in a:
        if key in timing:
            continue
        va, vb = a[key], b[key]
        if isinstance(va, float) and math.isnan(va):
            assert math.isnan(vb), key
        else:
            assert va == vb, key
    assert other["mean_human_distance"] != a["mean_human_distance"]


def test_ray_executor(tmp_path):
    ray = pytest.importorskip("ray", reason="ray is not installed (extra 'ray')")
    try:
        ray.init(num_cpus=1, include_dashboard=False, log_to_driver=False)
    except Exception as e:  # noqa: BLE001
        pytest.skip(f"a local Ray instance cannot start here: {e}")
    try:
        result = RunCampaign(
            STUDIES["adversarial"],
            tmp_path,
            runs=1,
            only="adversarial",
            duration=2.0,
            executor="ray",
            progress=False,
        )
    finally:
        ray.shutdown()
    assert result.ran == 2
    assert [r["status"] for r in result.rows] == ["ok", "ok"]


def test_a_foreign_csv_is_refused(tmp_path):
    (tmp_path / "adversarial.csv").write_text("run_id,something\nx,1\n")
    result = _cli("experiment", "adversarial", "--out", str(tmp_path), cwd=tmp_path)
    assert result.returncode == 2
    assert "other columns" in result.stderr and "Traceback" not in result.stderr
