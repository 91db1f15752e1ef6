"""Loading named scenarios: the one loader every command uses."""

from pathlib import Path

import yaml
from pydrake.common.yaml import yaml_load_typed

from sm2ith_drake.resources import ResolveScenarioFile
from sm2ith_drake.robots import MobileManipulator
from sm2ith_drake.scenario import Scenario, ScenarioError
from sm2ith_drake.scenario_checks import ValidateScenario, ValidateScenarioForRobot


def ScenarioNames(filename: str | Path) -> list[str]:
    """The names of the scenarios in a ``*.scenarios.yaml`` file."""
    path = ResolveScenarioFile(str(filename))
    try:
        with open(path) as f:
            data = yaml.safe_load(f)
    except yaml.YAMLError as e:
        raise ScenarioError(f"malformed YAML in {path}: {_OneLine(e)}") from e
    if not isinstance(data, dict):
        raise ScenarioError(f"{path} must map scenario names to scenarios")
    return [k for k in data if not str(k).startswith(".")]


def LoadScenario(
    *, filename: str | Path, scenario_name: str, scenario_text: str = "{}"
) -> Scenario:
    """Loads one named scenario, then applies the YAML ``scenario_text`` on top.

    Raises:
        FileNotFoundError: the file does not exist.
        ScenarioError: malformed YAML, unknown scenario name, unknown key or a
            value that fails validation.
    """
    path = ResolveScenarioFile(str(filename))
    names = ScenarioNames(path)
    if scenario_name not in names:
        raise ScenarioError(
            f"unknown scenario '{scenario_name}' in {path}; valid names: "
            + ", ".join(names)
        )
    try:
        scenario = yaml_load_typed(
            schema=Scenario, filename=str(path), child_name=scenario_name
        )
    except (RuntimeError, ValueError, TypeError, yaml.YAMLError) as e:
        raise ScenarioError(f"{path}:{scenario_name}: {_OneLine(e)}") from e
    try:
        return ApplyScenarioText(scenario, scenario_text)
    except ScenarioError as e:
        raise ScenarioError(f"{path}:{scenario_name}: {e}") from e


def ApplyScenarioText(scenario: Scenario, scenario_text: str) -> Scenario:
    """The YAML ``scenario_text`` applied on top of ``scenario``, validated.

    Raises:
        ScenarioError: malformed YAML, an unknown key or a value that fails
            validation.
    """
    if scenario_text.strip():
        try:
            scenario = yaml_load_typed(
                schema=Scenario,
                data=scenario_text,
                defaults=scenario,
                retain_map_defaults=True,
            )
        except (RuntimeError, ValueError, TypeError, yaml.YAMLError) as e:
            raise ScenarioError(_OneLine(e)) from e
    ValidateScenario(scenario)
    return scenario


def MakeRobot(scenario: Scenario) -> MobileManipulator:
    """The scenario's MobileManipulator, with its joint-limit overrides."""
    robot = MobileManipulator(
        scenario.robot.model, urdf_path=scenario.robot.urdf_path or None
    )
    robot.NarrowJointLimits(scenario.robot.joint_limits)
    return robot


def LoadScenarioAndRobot(
    *, filename: str | Path, scenario_name: str, scenario_text: str = "{}"
) -> tuple[Scenario, MobileManipulator]:
    """LoadScenario, then the robot it names (the robot's own checks: URDF,
    joint limits). Raises ScenarioError (or FileNotFoundError) only."""
    scenario = LoadScenario(
        filename=filename, scenario_name=scenario_name, scenario_text=scenario_text
    )
    try:
        robot = MakeRobot(scenario)
    except ValueError as e:
        raise ScenarioError(_OneLine(e)) from e
    ValidateScenarioForRobot(scenario, robot)
    return scenario, robot


def _OneLine(e: Exception) -> str:
    return " ".join(str(e).split())
