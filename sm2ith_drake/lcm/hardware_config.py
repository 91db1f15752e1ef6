"""The hardware section of a scenario: its checks and the timeouts derived
from it."""

from __future__ import annotations

from sm2ith_drake.scenario import ControlPeriod, HardwareConfig, Scenario, ScenarioError

# Messages are published this long after the control step (or the driver's
# step), so that they carry the step's result (Drake handles publish events
# at t before the updates at t) and leave as soon as it is computed.
PUBLISH_DELAY = 1e-3


def ValidateHardwareConfig(config: HardwareConfig) -> None:
    """Checks the values of ``config``; raises ScenarioError."""

    for name in ("state", "command", "detections", "plan"):
        if not getattr(config, f"{name}_channel"):
            raise ScenarioError(f"hardware.{name}_channel must not be empty")
    if config.poll_period <= 0 or config.driver_state_period <= 0:
        raise ScenarioError("hardware.poll_period and driver_state_period must be > 0")
    for name in (
        "state_timeout",
        "detection_timeout",
        "detection_stop_timeout",
        "driver_command_timeout",
    ):
        if getattr(config, name) < 0:
            raise ScenarioError(f"hardware.{name} must be ≥ 0")
    if not 0 <= config.stale_detection_speed_scale <= 1:
        raise ScenarioError("hardware.stale_detection_speed_scale must be in [0, 1]")
    if any(i < 0 for i in config.human_ids):
        raise ScenarioError("hardware.human_ids must be ≥ 0")


def StateTimeout(scenario: Scenario) -> float:
    """hardware.state_timeout, or two control periods if it is 0."""
    h = scenario.hardware
    return (
        h.state_timeout
        if h.state_timeout > 0
        else 2 * ControlPeriod(scenario.controller)
    )


def DetectionStopTimeout(scenario: Scenario) -> float:
    """hardware.detection_stop_timeout, or the estimator's track timeout."""
    h = scenario.hardware
    if h.detection_stop_timeout > 0:
        return h.detection_stop_timeout
    return scenario.perception.track_timeout
