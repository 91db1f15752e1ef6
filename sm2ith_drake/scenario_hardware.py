"""The hardware path's configuration (Scenario.hardware), kept apart from
scenario.py for its length; scenario.py re-exports it."""

from dataclasses import dataclass, field

from pydrake.lcm import DrakeLcmParams


@dataclass
class HardwareConfig:
    """The hardware path over LCM (``sm2ith hardware`` and ``sm2ith driver``):
    channels, timeouts and what happens when inputs go stale."""

    # Drake's LCM parameters. The default URL is multicast that never leaves
    # the host (ttl=0).
    lcm: DrakeLcmParams = field(
        default_factory=lambda: DrakeLcmParams(
            lcm_url="udpm://239.255.76.67:7667?ttl=0"
        )
    )
    state_channel: str = "SM2ITH_ROBOT_STATE"
    command_channel: str = "SM2ITH_ROBOT_COMMAND"
    detections_channel: str = "SM2ITH_HUMAN_DETECTIONS"
    plan_channel: str = "SM2ITH_PLAN"
    # Robot state older than this (s, since it was received) or missing:
    # stop commands. 0: two control periods.
    state_timeout: float = 0.0
    # Human detections older than this (s): the estimator only predicts and
    # the velocity command is scaled by stale_detection_speed_scale; older
    # than detection_stop_timeout (0: perception.track_timeout, when the
    # tracks are dropped): stop commands.
    detection_timeout: float = 0.25
    stale_detection_speed_scale: float = 0.3
    detection_stop_timeout: float = 0.0
    # Listen to motion capture and predict people (whatever ``humans``
    # lists: on hardware they are only what the driver simulates).
    with_people: bool = True
    # Detection ids accepted (empty: any id ≥ 0); others are dropped and
    # counted.
    human_ids: list[int] = field(default_factory=list)
    # How often incoming messages are polled and validated (s).
    poll_period: float = 0.005
    # Publish the plan for telemetry on plan_channel.
    publish_plan: bool = True
    # The driver: state publication period (s), and the watchdog that brakes
    # the robot when no command arrives for this long (s).
    driver_state_period: float = 0.01
    driver_command_timeout: float = 0.5
