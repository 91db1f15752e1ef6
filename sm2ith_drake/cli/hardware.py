"""``sm2ith hardware`` and ``sm2ith driver``."""

from __future__ import annotations

import ipaddress
import json
import sys
from pathlib import Path
from urllib.parse import urlsplit

from pydrake.lcm import DrakeLcm

from sm2ith_drake.diagrams.hardware import MakeHardwareDiagram
from sm2ith_drake.errors import UserError
from sm2ith_drake.lcm.hardware_config import ValidateHardwareConfig
from sm2ith_drake.robots import MODELS, MobileManipulator
from sm2ith_drake.run.hardware import RunDriver, RunHardware
from sm2ith_drake.run.walkers import ScriptedWalkers
from sm2ith_drake.scenario import Scenario, ScenarioError
from sm2ith_drake.scenario_loader import LoadScenarioAndRobot


def _LoadScenario(filename: str, name: str, text: str = "{}"):
    try:
        scenario, robot = LoadScenarioAndRobot(
            filename=filename, scenario_name=name, scenario_text=text
        )
        ValidateHardwareConfig(scenario.hardware)
    except (FileNotFoundError, ScenarioError, ValueError) as e:
        raise UserError(str(e)) from e
    return scenario, robot


def _SplitScenarioRef(ref: str, option: str) -> tuple[str, str]:
    """'FILE:NAME' → (FILE, NAME)."""
    path, sep, name = ref.rpartition(":")
    if not sep or not path or not name:
        raise UserError(f"{option} takes FILE:SCENARIO, got '{ref}'")
    return path, name


_LCM_PROVIDERS = ("udpm", "mpudpm", "memq", "file", "tcpq")


def CheckLcmUrl(url: str) -> None:
    """Raises UserError for a URL that LCM cannot open (DrakeLcm only prints
    an error and then silently drops every message). Opens nothing."""
    if not url:
        return  # LCM's default ($LCM_DEFAULT_URL or its udpm default)
    scheme = url.split("://", 1)[0] if "://" in url else ""
    if scheme not in _LCM_PROVIDERS:
        raise UserError(
            f"LCM URL '{url}': the provider must be one of "
            + ", ".join(f"{p}://" for p in _LCM_PROVIDERS)
        )
    if scheme in ("udpm", "mpudpm"):
        try:
            parts = urlsplit(url)
            address = ipaddress.ip_address(parts.hostname or "")
            parts.port  # noqa: B018 (raises for a malformed port)
        except ValueError as e:
            raise UserError(f"LCM URL '{url}': {e}") from e
        if not address.is_multicast:
            raise UserError(f"LCM URL '{url}': {address} is not a multicast address")


def _MakeLcm(params, url: str | None):
    if url is not None:
        params.lcm_url = url
    CheckLcmUrl(params.lcm_url)
    try:
        return DrakeLcm(params)
    except RuntimeError as e:
        raise UserError(f"cannot open LCM '{params.lcm_url}': {e}") from e


def _WriteJson(path: str | None, data: dict) -> None:
    if path:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        Path(path).write_text(json.dumps(data, indent=2))
        print(f"wrote {path}")


def _Ms(stats, key="median") -> str:
    return "n/a" if not stats else f"{stats[key]:.1f} ms"


def _Hardware(args) -> int:
    scenario, robot = _LoadScenario(args.file, args.scenario, args.scenario_text)
    if args.duration is not None and args.duration <= 0:
        raise UserError("--duration must be > 0")
    h = scenario.hardware
    lcm = _MakeLcm(h.lcm, args.lcm_url)
    if args.graphviz:
        diagram = MakeHardwareDiagram(scenario=scenario, lcm=lcm, robot=robot)
        Path(args.graphviz).write_text(diagram.GetGraphvizString(max_depth=2))
        print(f"wrote {args.graphviz}")
    print(
        f"sm2ith hardware: {args.scenario} ({scenario.robot.model}) on "
        f"{lcm.get_lcm_url()}: state '{h.state_channel}', command "
        f"'{h.command_channel}'"
        + (f", detections '{h.detections_channel}'" if h.with_people else "")
        + (f", plan '{h.plan_channel}'" if h.publish_plan else "")
        + "; Ctrl-C stops the robot and exits",
        flush=True,
    )
    summary = RunHardware(
        scenario,
        lcm=lcm,
        duration=args.duration,
        log=None if args.quiet else sys.stderr,
    )
    t, c = summary["timing"], summary["controller"]
    print(
        f"ended by {summary['ended_by']} after {summary['time']:.1f} s; "
        f"{t['commands']} commands {t['modes']}; final command: "
        f"{summary['final_command']['mode']}"
    )
    print(
        f"control-period jitter p95 {_Ms(t['control_jitter_ms'], 'p95')} "
        f"(publication {_Ms(t['publish_jitter_ms'], 'p95')}); latency "
        f"(state read → command sent) median {_Ms(t['latency_ms'])} vs solve "
        f"median {_Ms(c['solve_ms'])} (whole control step {_Ms(c['step_ms'])}); "
        f"state age at the step {_Ms(t['state_age_ms'])}; robot stamp → command "
        f"{_Ms(t['end_to_end_ms'])}"
    )
    hw = summary["hardware"]
    for name in ("robot_state", "detections"):
        if name in hw:
            print(
                f"{name}: {hw[name]['accepted']}/{hw[name]['received']} accepted, "
                f"rejected {hw[name]['rejected'] or 'none'}"
            )
    print(f"controller counters: {c['counters']}")
    _WriteJson(args.json, summary)
    return 0


def _ParseFloats(text: str, option: str) -> list[float]:
    try:
        return [float(v) for v in text.replace(",", " ").split()]
    except ValueError as e:
        raise UserError(f"{option}: not a list of numbers: '{text}'") from e


def _Driver(args) -> int:
    if args.scenario:
        scenario, robot = _LoadScenario(*_SplitScenarioRef(args.scenario, "--scenario"))
        if scenario.robot.model != args.robot:
            raise UserError(
                f"--robot {args.robot} but the scenario's robot is "
                f"{scenario.robot.model}"
            )
    else:
        scenario = Scenario()
        scenario.robot.model = args.robot
        robot = MobileManipulator(args.robot)
    if args.humans is not None:
        if args.humans.strip().isdigit():
            scenario.humans = ScriptedWalkers(
                int(args.humans),
                x_start=3.0,
                x_span=2.0,
                half_width=3.0,
                base_speed=0.7,
            )
        else:
            people, _ = _LoadScenario(*_SplitScenarioRef(args.humans, "--humans"))
            # The people walk as in their own scenario: "relaxed_orca" people
            # follow its prediction model, at its crowd time step.
            scenario.humans = list(people.humans)
            scenario.prediction = people.prediction
            scenario.crowd_time_step = people.crowd_time_step
    try:
        ValidateHardwareConfig(scenario.hardware)
    except ScenarioError as e:
        raise UserError(str(e)) from e
    initial_q = scenario.robot.initial_q or list(robot.default_q)
    if args.initial_q is not None:
        initial_q = _ParseFloats(args.initial_q, "--initial_q")
    if len(initial_q) != robot.num_positions:
        raise UserError(
            f"--initial_q needs {robot.num_positions} numbers for {args.robot}, "
            f"got {len(initial_q)}"
        )
    scenario.robot.initial_q = list(initial_q)
    scenario.random_seed = args.seed
    if args.duration is not None and args.duration <= 0:
        raise UserError("--duration must be > 0")
    h = scenario.hardware
    lcm = _MakeLcm(h.lcm, args.lcm_url)
    print(
        f"sm2ith driver: {args.robot} with {len(scenario.humans)} simulated people "
        f"on {lcm.get_lcm_url()}: state '{h.state_channel}' every "
        f"{h.driver_state_period * 1e3:.0f} ms, detections "
        f"'{h.detections_channel}' every {scenario.perception.period * 1e3:.0f} "
        f"ms, commands '{h.command_channel}' (watchdog "
        f"{h.driver_command_timeout:.2f} s)",
        flush=True,
    )
    summary = RunDriver(
        scenario,
        robot=robot,
        lcm=lcm,
        duration=args.duration,
        log=None if args.quiet else sys.stderr,
    )
    c, t = summary["commands"], summary["timing"]
    print(
        f"ended by {summary['ended_by']} after {summary['time']:.1f} s; "
        f"commands {c['accepted']}/{c['received']} accepted, rejected "
        f"{c['rejected'] or 'none'}; modes {t['modes']}; robot stamp → "
        f"command {_Ms(t['end_to_end_ms'])}"
    )
    _WriteJson(args.json, summary)
    return 0


def AddHardwareCommands(sub) -> None:
    """Registers ``hardware`` and ``driver`` on the ``sm2ith`` parser."""

    hw = sub.add_parser(
        "hardware",
        help="run the controller in real time against a robot over LCM",
        description="Runs the scenario's controller in real time: robot state "
        "and human detections in, velocity commands out, over LCM (channels "
        "and URL from the scenario's `hardware` section). Stale or missing "
        "robot state gives stop commands; Ctrl-C sends a final stop command "
        "and exits.",
    )
    hw.add_argument("file", help="a diagrams/*.scenarios.yaml file")
    hw.add_argument("--scenario", required=True, help="scenario name in the file")
    hw.add_argument(
        "--scenario_text",
        default="{}",
        help="YAML applied on top of the scenario, e.g. "
        "'{hardware: {state_timeout: 0.5}}'",
    )
    hw.add_argument(
        "--lcm-url",
        "--lcm_url",
        dest="lcm_url",
        default=None,
        help="LCM URL (default: the scenario's hardware.lcm.lcm_url, "
        "udpm://239.255.76.67:7667?ttl=0)",
    )
    hw.add_argument(
        "--duration", type=float, default=None, help="seconds (default: until Ctrl-C)"
    )
    hw.add_argument("--json", default=None, help="write the run's figures as JSON")
    hw.add_argument("--graphviz", default=None, help="write the diagram (.dot)")
    hw.add_argument("--quiet", action="store_true", help="no periodic status lines")
    hw.set_defaults(func=_Hardware)

    drv = sub.add_parser(
        "driver",
        help="play the robot and the motion capture over LCM (no robot needed)",
        description="A stand-in for the robot and the motion capture: "
        "integrates the commands within the robot's limits and publishes its "
        "state, and publishes detections of simulated people, so that "
        "`sm2ith hardware` can be run without a robot. Without commands for "
        "hardware.driver_command_timeout the robot brakes to a stop.",
    )
    drv.add_argument("--robot", required=True, choices=sorted(MODELS))
    drv.add_argument(
        "--scenario",
        default=None,
        metavar="FILE:NAME",
        help="take the start pose, the people, the motion capture settings "
        "and the LCM channels from this scenario",
    )
    drv.add_argument(
        "--humans",
        default=None,
        metavar="N|FILE:NAME",
        help="the simulated people: N people pacing across the room ahead of "
        "the robot (x = 3…5 m), or the people of a scenario (default: the "
        "--scenario's, else none)",
    )
    drv.add_argument(
        "--initial_q",
        default=None,
        help="start configuration, comma separated (default: the scenario's "
        "or the robot's nominal one)",
    )
    drv.add_argument(
        "--lcm-url", "--lcm_url", dest="lcm_url", default=None, help="LCM URL"
    )
    drv.add_argument(
        "--duration", type=float, default=None, help="seconds (default: until Ctrl-C)"
    )
    drv.add_argument("--seed", type=int, default=0, help="motion-capture noise seed")
    drv.add_argument("--json", default=None, help="write the run's figures as JSON")
    drv.add_argument("--quiet", action="store_true", help="no periodic status lines")
    drv.set_defaults(func=_Driver)
