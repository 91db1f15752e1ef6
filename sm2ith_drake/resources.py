"""Locates the data shipped with the package (robot models, scenario files).

``models/`` and ``diagrams/`` sit at the top of a checkout and are installed as
the data packages ``sm2ith_drake.model_files`` and
``sm2ith_drake.scenario_files``, so the
same lookup works from an editable install, a wheel, or a plain checkout.
"""

from __future__ import annotations

import importlib.resources
from pathlib import Path

_CHECKOUT_ROOT = Path(__file__).resolve().parent.parent


def _data_dir(package: str, checkout_name: str) -> Path:
    try:
        path = Path(str(importlib.resources.files(package)))
        if path.is_dir():
            return path
    except (ModuleNotFoundError, TypeError):
        pass
    return _CHECKOUT_ROOT / checkout_name


def GetModelsDir() -> Path:
    """The directory holding the robot URDFs and their ``package.xml``."""
    return _data_dir("sm2ith_drake.model_files", "models")


def GetDiagramsDir() -> Path:
    """The directory holding the shipped ``*.scenarios.yaml`` files."""
    return _data_dir("sm2ith_drake.scenario_files", "diagrams")


def ResolveScenarioFile(filename: str) -> Path:
    """Returns ``filename`` if it exists, else the shipped file of that name.

    This lets ``sm2ith run diagrams/foo.scenarios.yaml`` work from any
    directory once the package is installed.
    """
    path = Path(filename)
    if path.exists():
        return path
    shipped = GetDiagramsDir() / path.name
    if shipped.exists():
        return shipped
    raise FileNotFoundError(f"scenario file not found: {filename}")
