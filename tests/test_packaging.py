"""models/ and diagrams/ work from an installed wheel, not only a checkout."""

import os
import subprocess
import sys
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def test_wheel_ships_models_and_scenarios(tmp_path):
    wheels = tmp_path / "wheels"
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            str(ROOT),
            "--no-deps",
            "--no-build-isolation",
            "-q",
            "-w",
            str(wheels),
        ],
        check=True,
        capture_output=True,
        timeout=600,
    )
    (wheel,) = wheels.glob("sm2ith_drake-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    for model in ("stretch3.urdf", "ridgeback_ur10.urdf"):
        assert f"sm2ith_drake/model_files/{model}" in names
    shipped = {
        Path(n).name for n in names if n.startswith("sm2ith_drake/scenario_files/")
    }
    assert {p.name for p in (ROOT / "diagrams").glob("*.scenarios.yaml")} <= shipped

    # Installed elsewhere and run from an unrelated directory, the package
    # finds its own data (not the checkout's).
    target = tmp_path / "site"
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "install",
            "--no-deps",
            "-q",
            "--target",
            str(target),
            str(wheel),
        ],
        check=True,
        capture_output=True,
        timeout=600,
    )
    code = (
        "from sm2ith_drake.resources import GetModelsDir, GetDiagramsDir\n"
        "from sm2ith_drake.robots import MobileManipulator\n"
        "from sm2ith_drake.scenario_loader import LoadScenario\n"
        "print(GetModelsDir()); print(GetDiagramsDir())\n"
        "MobileManipulator('stretch3')\n"
        "LoadScenario(filename='diagrams/reach.scenarios.yaml',"
        " scenario_name='stretch3_reach')\n"
    )
    env = dict(os.environ, PYTHONPATH=str(target))
    out = subprocess.run(
        [sys.executable, "-c", code],
        cwd=tmp_path,
        env=env,
        check=True,
        capture_output=True,
        text=True,
        timeout=300,
    )
    models_dir, diagrams_dir = out.stdout.split()
    assert models_dir.startswith(str(target)) and diagrams_dir.startswith(str(target))
