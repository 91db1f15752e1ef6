"""The saved HTML replay opens in a real headless browser and shows the robot."""

import os

import numpy as np
import pytest
from browser_shots import CHROMIUM, Screenshot

from sm2ith_drake.resources import GetDiagramsDir
from sm2ith_drake.run.simulation import RunSimulation
from sm2ith_drake.scenario_loader import LoadScenario


@pytest.mark.skipif(
    CHROMIUM is None and not os.environ.get("CI"),
    reason="Debian's chromium is not installed (.ci/run installs it)",
)
def test_html_replay_shows_robot(tmp_path):
    assert CHROMIUM is not None, "CI must install chromium"
    from pydrake.geometry import Meshcat

    meshcat = Meshcat()
    # The same viewer without a robot: the background and grid only.
    empty_html = tmp_path / "empty.html"
    empty_html.write_text(meshcat.StaticHtml())
    scenario = LoadScenario(
        filename=GetDiagramsDir() / "reach.scenarios.yaml",
        scenario_name="ridgeback_ur10_reach",
    )
    html = tmp_path / "replay.html"
    result = RunSimulation(scenario, meshcat=meshcat, duration=1.0, html_path=str(html))
    assert result.html_path == str(html)
    text = html.read_text()
    assert "<html" in text.lower() and len(text) > 100_000
    background = Screenshot(empty_html, tmp_path / "empty.png", tmp_path / "ud1")
    replay = Screenshot(html, tmp_path / "replay.png", tmp_path / "ud2")
    assert replay.shape == background.shape
    # The scene area (below the controls bar): pixels that are not background.
    diff = np.abs(replay[40:] - background[40:]).max(axis=-1)
    changed = np.mean(diff > 0.1)
    assert changed > 0.01, f"only {changed:.2%} of the scene differs from background"
