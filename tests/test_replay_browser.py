"""The saved HTML replay opens in a real headless browser and shows the robot."""

import os
import shutil
import subprocess

import numpy as np
import pytest

from sm2ith_drake.resources import GetDiagramsDir
from sm2ith_drake.run.simulation import RunSimulation
from sm2ith_drake.scenario_loader import LoadScenario

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


def _screenshot(html, png, user_data_dir):
    subprocess.run(
        [
            CHROMIUM,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            f"--user-data-dir={user_data_dir}",
            "--window-size=800,600",
            "--virtual-time-budget=8000",
            f"--screenshot={png}",
            f"file://{html}",
        ],
        capture_output=True,
        timeout=180,
        check=True,
    )
    import matplotlib.image

    return matplotlib.image.imread(str(png))[..., :3]


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
    background = _screenshot(empty_html, tmp_path / "empty.png", tmp_path / "ud1")
    replay = _screenshot(html, tmp_path / "replay.png", tmp_path / "ud2")
    assert replay.shape == background.shape
    # The scene area (below the controls bar): pixels that are not background.
    diff = np.abs(replay[40:] - background[40:]).max(axis=-1)
    changed = np.mean(diff > 0.1)
    assert changed > 0.01, f"only {changed:.2%} of the scene differs from background"
