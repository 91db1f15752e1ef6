"""Running the hardware path in real time, with status lines and a summary:
``sm2ith hardware`` (the controller over LCM, :func:`RunHardware`) and
``sm2ith driver`` (the robot and the motion capture it talks to,
:func:`RunDriver`).
"""

from __future__ import annotations

import copy
import math

import numpy as np
from pydrake.lcm import DrakeLcm
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import EventStatus

from sm2ith_drake.control.hierarchy import SolvedThrough
from sm2ith_drake.diagrams.driver import MakeDriverDiagram
from sm2ith_drake.diagrams.hardware import (
    GetCommandTiming,
    GetHardwareStatus,
    MakeHardwareDiagram,
)
from sm2ith_drake.lcm.codecs import MakeCommandMessage
from sm2ith_drake.lcm.command_gate import MODE_NAMES, MODE_STOP, GateCommand, GateState
from sm2ith_drake.lcm.sm2ith_lcmtypes import lcmt_sm2ith_robot_command
from sm2ith_drake.lcm.timing import CommandTiming, StopRequest
from sm2ith_drake.run.realtime import FreezeHeap
from sm2ith_drake.scenario import ControlPeriod, Scenario
from sm2ith_drake.scenario_loader import MakeRobot


def PublishStopCommand(
    lcm, scenario: Scenario, robot, nu, gate=None
) -> lcmt_sm2ith_robot_command:
    """Publishes one stop command (ν_cmd = 0, braking from ``nu``) and
    returns it."""
    period = ControlPeriod(scenario.controller)
    gate = copy.copy(gate) if gate is not None else GateState()
    gate.mode, gate.speed_scale = MODE_STOP, 0.0
    command = GateCommand(
        robot,
        np.zeros(2 * robot.num_velocities),
        nu,
        mode=MODE_STOP,
        speed_scale=0.0,
        period=period,
    )
    msg = MakeCommandMessage(command, gate)
    lcm.Publish(scenario.hardware.command_channel, msg.encode())
    return msg


def RunHardware(
    scenario: Scenario,
    *,
    lcm=None,
    duration: float | None = None,
    realtime_rate: float = 1.0,
    report_period: float = 5.0,
    log=None,
    stop_request: StopRequest | None = None,
) -> dict:
    """Runs the controller of ``scenario`` against LCM until ``duration``
    (None: forever) or SIGINT / SIGTERM, then publishes one final stop
    command.

    Args:
        scenario: the configuration (``scenario.hardware`` for LCM).
        lcm: a DrakeLcm (default: one made from ``scenario.hardware.lcm``).
        duration: seconds to run (None: until a signal).
        realtime_rate: 1.0 on hardware; tests may run faster on memq://.
        report_period: seconds between status lines on ``log``.
        log: a text stream for status lines (None: quiet).

    Returns:
        A summary dict: timing (CommandTiming.Summary), the controller's
        solve and step times (ms), its counters, the hardware counters, the
        final task errors and why the run ended.
    """

    robot = MakeRobot(scenario)
    lcm = lcm if lcm is not None else DrakeLcm(scenario.hardware.lcm)
    diagram = MakeHardwareDiagram(scenario=scenario, lcm=lcm, robot=robot)
    simulator = Simulator(diagram)
    simulator.set_target_realtime_rate(realtime_rate)
    root = simulator.get_context()
    hardware = diagram.GetSubsystemByName("hardware")
    timing = GetCommandTiming(diagram, root)
    end = math.inf if duration is None else float(duration)
    with stop_request or StopRequest() as stop:

        def monitor(context):
            if stop.requested:
                return EventStatus.ReachedTermination(diagram, "stop requested")
            return EventStatus.Succeeded()

        simulator.set_monitor(monitor)
        reason = "error"
        try:
            simulator.Initialize()
            FreezeHeap()
            next_report = report_period
            while not stop.requested and root.get_time() < end:
                simulator.AdvanceTo(min(end, root.get_time() + 0.5))
                if log is not None and root.get_time() >= next_report:
                    next_report += report_period
                    print(_StatusLine(diagram, root, timing), file=log, flush=True)
            reason = "signal" if stop.requested else "duration"
        finally:
            # Whatever ended the run (even an exception), the robot is told
            # to stop.
            state_rx = hardware.GetSubsystemByName("robot_state.receiver")
            x = state_rx.GetOutputPort("state").Eval(
                state_rx.GetMyContextFromRoot(root)
            )
            gate = hardware.GetSubsystemByName("command_gate")
            final = PublishStopCommand(
                lcm,
                scenario,
                robot,
                np.asarray(x)[robot.num_positions :],
                gate.GetGateState(gate.GetMyContextFromRoot(root)),
            )
    summary = _Summary(diagram, root, timing)
    summary["ended_by"] = reason
    summary["final_command"] = {
        "mode": MODE_NAMES[final.mode],
        "velocity": list(final.velocity),
        "acceleration": list(final.acceleration),
    }
    if log is not None:
        print(_StatusLine(diagram, root, timing), file=log, flush=True)
    return summary


def _ControllerFigures(diagram, root) -> dict:
    logger = diagram.GetSubsystemByName("logger")
    log = logger.GetLog(logger.GetMyContextFromRoot(root))
    records = [r for r in log.records if r.mode != "none"]
    # The first step includes the solver's setup.
    steady = records[1:] if len(records) > 1 else records
    out = {
        "steps": len(records),
        # Solved steps whose lower stages went unoptimized (a lower stage's
        # QP failed, or controller.qp_iteration_budget ran out).
        "solved_through": sum(SolvedThrough(r.status) for r in records),
    }
    for key, attr in (("solve_ms", "solve_time"), ("step_ms", "wall_time")):
        values = np.array([getattr(r, attr) for r in steady]) * 1e3
        out[key] = (
            {
                "median": float(np.median(values)),
                "p95": float(np.percentile(values, 95)),
                "max": float(values.max()),
            }
            if len(values)
            else None
        )
    counters = log.counters
    out["counters"] = dict(vars(counters)) if counters is not None else {}
    out["task_errors"] = {
        name: float(np.linalg.norm(errors[-1]))
        for name, errors in log.task_errors.items()
        if errors
    }
    return out


def _People(diagram, root) -> dict:
    """At the last prediction: the people in the program's slots, the
    extras the barrier keeps out of, and those the controller does not see
    (more than max_humans + max_extra_humans); {} without people."""
    if not diagram.HasSubsystemNamed("human_predictor"):
        return {}
    predictor = diagram.GetSubsystemByName("human_predictor")
    state = predictor.GetPredictorState(predictor.GetMyContextFromRoot(root))
    last = state.last_prediction
    if last is None:
        return {"predicted": 0, "extra": 0, "unseen": 0}
    return {
        "predicted": int(np.sum(last.active)),
        "extra": int(np.sum(np.asarray(last.extra_ids) >= 0)),
        "unseen": int(last.dropped),
    }


def _Summary(diagram, root, timing: CommandTiming) -> dict:
    summary = {
        "time": float(root.get_time()),
        "timing": timing.Summary(),
        "controller": _ControllerFigures(diagram, root),
        "hardware": GetHardwareStatus(diagram, root),
        "people": _People(diagram, root),
    }
    lat = summary["timing"]["latency_ms"]
    solve = summary["controller"]["solve_ms"]
    if lat and solve and solve["median"] > 0:
        summary["latency_over_solve"] = lat["median"] / solve["median"]
    return summary


def _StatusLine(diagram, root, timing: CommandTiming) -> str:
    t = timing.Summary()
    hw = GetHardwareStatus(diagram, root)

    def ms(stats, key="median"):
        return "n/a" if not stats else f"{stats[key]:.1f}"

    ctrl = _ControllerFigures(diagram, root)
    parts = [
        f"t={root.get_time():.1f}s",
        f"commands {t['commands']} {t['modes']}",
        f"control jitter p95 {ms(t['control_jitter_ms'], 'p95')} ms",
        f"latency {ms(t['latency_ms'])} ms (solve {ms(ctrl['solve_ms'])} ms)",
        f"lower stages cut {ctrl['solved_through']}",
        f"gate: {hw['gate']['mode']}",
    ]
    people = _People(diagram, root)
    if people:
        parts.append(
            f"people {people['predicted']} predicted + {people['extra']} "
            f"extra, {people['unseen']} unseen"
        )
    for name in ("robot_state", "detections"):
        if name in hw:
            parts.append(
                f"{name} {hw[name]['accepted']}/{hw[name]['received']} "
                f"rejected {hw[name]['rejected'] or 0}"
            )
    return "sm2ith hardware: " + ", ".join(parts)


# ---------------------------------------------------------------------------
# The driver.


def RunDriver(
    scenario: Scenario,
    *,
    robot=None,
    lcm=None,
    duration: float | None = None,
    realtime_rate: float = 1.0,
    log=None,
    report_period: float = 5.0,
    stop_request: StopRequest | None = None,
) -> dict:
    """Runs the driver of ``scenario`` (see :func:`MakeDriverDiagram`) in real
    time until ``duration`` (None: forever) or SIGINT / SIGTERM.

    Args:
        scenario: what the driver plays (robot, people, motion capture,
            ``hardware`` channels).
        robot: the MobileManipulator (defaults to the scenario's).
        lcm: a DrakeLcm (default: one made from ``scenario.hardware.lcm``).
        duration: seconds to run (None: until a signal).
        realtime_rate: 1.0 for a robot stand-in.
        log: a text stream for status lines (None: quiet).
        report_period: seconds between status lines on ``log``.
        stop_request: the StopRequest that turns signals into a stop.

    Returns:
        A summary: the final state, the command counters and the timing of
        the commands received.
    """
    lcm = lcm if lcm is not None else DrakeLcm(scenario.hardware.lcm)
    diagram = MakeDriverDiagram(scenario=scenario, lcm=lcm, robot=robot)
    simulator = Simulator(diagram)
    simulator.set_target_realtime_rate(realtime_rate)
    root = simulator.get_context()
    end = math.inf if duration is None else float(duration)
    with stop_request or StopRequest() as stop:

        def monitor(context):
            if stop.requested:
                return EventStatus.ReachedTermination(diagram, "stop requested")
            return EventStatus.Succeeded()

        simulator.set_monitor(monitor)
        simulator.Initialize()
        next_report = report_period
        while not stop.requested and root.get_time() < end:
            simulator.AdvanceTo(min(end, root.get_time() + 0.5))
            if log is not None and root.get_time() >= next_report:
                next_report += report_period
                print(_DriverStatusLine(diagram, root), file=log, flush=True)
    summary = DriverSummary(diagram, root)
    summary["ended_by"] = "signal" if stop.requested else "duration"
    if log is not None:
        print(_DriverStatusLine(diagram, root), file=log, flush=True)
    return summary


def DriverSummary(diagram, root) -> dict:
    """The driver's state [q; ν], command counters and command timing."""
    robot = diagram.GetSubsystemByName("robot")
    x = np.array(robot.GetOutputPort("state").Eval(robot.GetMyContextFromRoot(root)))
    receiver = diagram.GetSubsystemByName("command.receiver")
    status = receiver.GetReceiverState(receiver.GetMyContextFromRoot(root))
    monitor = diagram.GetSubsystemByName("command.monitor")
    timing = monitor.GetTiming(monitor.GetMyContextFromRoot(root))
    return {
        "time": float(root.get_time()),
        "state": x.tolist(),
        "commands": {
            "received": status.counters.received,
            "accepted": status.counters.accepted,
            "rejected": dict(status.counters.rejected),
            "restarts": status.counters.restarts,
            "last_error": status.last_error,
        },
        "timing": timing.Summary(),
    }


def _DriverStatusLine(diagram, root) -> str:
    s = DriverSummary(diagram, root)
    c, t = s["commands"], s["timing"]
    lat = t["end_to_end_ms"]
    return (
        f"sm2ith driver: t={s['time']:.1f}s, commands {c['accepted']}/"
        f"{c['received']} rejected {c['rejected'] or 0}, modes {t['modes']}, "
        f"state→command "
        + ("n/a" if not lat else f"{lat['median']:.1f} ms")
        + f", x,y = {s['state'][0]:.2f}, {s['state'][1]:.2f}"
    )
