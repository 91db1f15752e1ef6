"""The ``sm2ith`` command line: run | bench.

Errors a user can cause (missing file, unknown scenario, malformed YAML, an
unknown key) print one line and exit with code 2, without a traceback.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

EXIT_USAGE = 2


# Defined in its own module so that `python -m sm2ith_drake.cli` and the
# subcommand modules raise and catch the same class.
from sm2ith_drake.errors import UserError  # noqa: E402


def _Load(filename: str, name: str, text: str):
    from sm2ith_drake.scenario import ScenarioError
    from sm2ith_drake.scenario_loader import LoadScenarioAndRobot

    try:
        scenario, _ = LoadScenarioAndRobot(
            filename=filename, scenario_name=name, scenario_text=text
        )
    except (FileNotFoundError, ScenarioError) as e:
        raise UserError(str(e)) from e
    return scenario


def _Run(args) -> int:
    from sm2ith_drake.diagrams import MakeSimulation, RunSimulation
    from sm2ith_drake.experiments.metrics import FormatMetrics

    scenario = _Load(args.file, args.scenario, args.scenario_text)
    if getattr(args, "seed", None) is not None:  # sm2ith replay
        from sm2ith_drake.experiments.campaign import ApplySeed

        scenario = ApplySeed(scenario, args.seed)
    if args.graphviz:
        diagram = MakeSimulation(scenario=scenario)
        _WriteGraphviz(diagram, args.graphviz)
        print(f"wrote {args.graphviz}")
    meshcat = None
    html = args.html
    if not args.no_meshcat:
        from pydrake.geometry import Meshcat

        meshcat = Meshcat()
        print(f"Meshcat: {meshcat.web_url()}")
        if html is None:
            html = str(Path("out") / f"{args.scenario}.html")
    elif html:
        raise UserError("--html needs Meshcat; drop --no-meshcat")
    rate = args.realtime_rate
    if rate is None:
        rate = 1.0 if meshcat is not None else 0.0
    if rate < 0 or (args.duration is not None and args.duration <= 0):
        raise UserError("--realtime_rate must be ≥ 0 and --duration > 0")
    result = RunSimulation(
        scenario,
        meshcat=meshcat,
        duration=args.duration,
        html_path=html,
        progress=sys.stderr.isatty(),
        realtime_rate=rate,
        stop_when_done=getattr(args, "stop_when_done", False),
    )
    print(
        f"scenario {args.scenario} ({scenario.robot.model}, "
        f"{scenario.controller.method}/{scenario.controller.solver}):"
    )
    print(FormatMetrics(result.metrics))
    if result.html_path:
        print(f"replay saved to {result.html_path} (open it in any browser)")
    if args.wait and meshcat is not None:
        print(
            f"Meshcat still at {meshcat.web_url()} (the recording plays there); "
            "press Enter or Ctrl-C to quit"
        )
        try:
            input()
        except (EOFError, KeyboardInterrupt):
            pass
    return 0


def _WriteGraphviz(diagram, path: str) -> None:
    dot = diagram.GetGraphvizString(max_depth=1)
    if path.endswith(".dot"):
        Path(path).write_text(dot)
        return
    try:
        import pydot
    except ImportError as e:
        raise UserError("writing an image needs pydot; use a .dot file name") from e
    (graph,) = pydot.graph_from_dot_data(dot)
    fmt = Path(path).suffix.lstrip(".") or "svg"
    graph.write(path, format=fmt)


def BenchmarkScenario(
    robot: str,
    humans: int,
    predictor: str,
    solver: str = "rti",
    rti_iterations: int | None = None,
    scenario_text: str = "",
):
    """The benchmark scenario: the robot's reach task with ``humans``
    scripted people pacing across its way; ``scenario_text`` (YAML) is
    applied on top, e.g. "{prediction: {max_neighbors: 9}}"."""
    from sm2ith_drake.resources import GetDiagramsDir
    from sm2ith_drake.scenario import HumanConfig, ScenarioError
    from sm2ith_drake.scenario_loader import ApplyScenarioText

    if humans < 0:
        raise UserError("--humans must be ≥ 0")
    text = f"{{controller: {{solver: {solver}}}}}"
    scenario = _Load(
        str(GetDiagramsDir() / "benchmark.scenarios.yaml"), f"bench_{robot}", text
    )
    # People pacing back and forth across the robot's way (scripted, so the
    # crowd is the same for every predictor), seen without perception noise.
    for j in range(humans):
        x = 0.8 + 2.4 * j / max(humans - 1, 1)
        side = 2.5 if j % 2 == 0 else -2.5
        scenario.humans.append(
            HumanConfig(
                behavior="scripted",
                start=[x, side],
                waypoints=[[x, -side], [x, side]],
                loop=True,
                speed=0.8 + 0.1 * (j % 3),
            )
        )
    scenario.prediction.predictor = predictor
    scenario.prediction.max_humans = max(humans, 1)
    scenario.perception.estimator = "truth"
    if humans and predictor == "orca_kkt":
        # As the shipped crowd scenarios: two SQP passes for the KKT model.
        scenario.controller.rti_iterations = 2
    if rti_iterations is not None:
        if rti_iterations < 1:
            raise UserError("--rti_iterations must be ≥ 1")
        scenario.controller.rti_iterations = rti_iterations
    try:
        return ApplyScenarioText(scenario, scenario_text)
    except ScenarioError as e:
        raise UserError(f"--scenario_text: {e}") from e


def RunBenchmark(
    *,
    robot: str,
    humans: int = 0,
    predictor: str = "orca_kkt",
    steps: int = 100,
    solver: str = "rti",
    rti_iterations: int | None = None,
    scenario_text: str = "",
) -> dict:
    """Runs the benchmark closed loop; returns the per-step timing figures."""
    from sm2ith_drake.diagrams import RunSimulation
    from sm2ith_drake.scenario import ControlPeriod

    scenario = BenchmarkScenario(
        robot, humans, predictor, solver, rti_iterations, scenario_text
    )
    # The logger sees a step at its next sample: run a little past step K
    # and keep the first K.
    duration = (steps + 0.5) * ControlPeriod(scenario.controller)
    result = RunSimulation(scenario, duration=duration)
    records = [r for r in result.log.records if r.mode != "none"][:steps]
    wall = np.array([r.wall_time for r in records]) * 1e3
    iters = np.array([r.iterations for r in records], dtype=float)
    return {
        "robot": robot,
        "humans": humans,
        "predictor": predictor if humans else "none",
        "solver": solver,
        "rti_iterations": scenario.controller.rti_iterations,
        "max_neighbors": scenario.prediction.max_neighbors,
        "scenario_text": scenario_text,
        "steps": len(records),
        "median_ms": float(np.median(wall)),
        "p95_ms": float(np.percentile(wall, 95)),
        "max_ms": float(wall.max()),
        # None when the solver does not report iterations (SNOPT, IPOPT).
        "mean_iterations": None if np.any(iters < 0) else float(iters.mean()),
        "mean_passes": float(np.mean([r.passes for r in records])),
        "solver_failures": int(
            sum(
                not r.status.startswith("solved") and not r.status.startswith("overrun")
                for r in records
            )
        ),
        "fallbacks": int(sum(r.mode != "solved" for r in records)),
    }


def _Bench(args) -> int:
    robots = ["ridgeback_ur10", "stretch3"] if args.robot == "all" else [args.robot]
    results = []
    for robot in robots:
        r = RunBenchmark(
            robot=robot,
            humans=args.humans,
            predictor=args.predictor,
            steps=args.steps,
            solver=args.solver,
            rti_iterations=args.rti_iterations,
            scenario_text=args.scenario_text,
        )
        results.append(r)
        iters = r["mean_iterations"]
        iters = "n/a" if iters is None else f"{iters:.1f}"
        print(
            f"{robot:15s} solver={r['solver']} steps={r['steps']}  "
            f"median {r['median_ms']:.1f} ms  p95 {r['p95_ms']:.1f} ms  "
            f"max {r['max_ms']:.1f} ms  mean iterations {iters}  "
            f"failures {r['solver_failures']}  fallbacks {r['fallbacks']}"
        )
    if args.json:
        Path(args.json).write_text(
            json.dumps(results[0] if len(results) == 1 else results, indent=2)
        )
        print(f"wrote {args.json}")
    return 0


def MakeParser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="sm2ith",
        description="SM2ITH mobile manipulation among people (Drake).",
    )
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="simulate a named scenario")
    run.add_argument("file", help="a diagrams/*.scenarios.yaml file")
    run.add_argument("--scenario", required=True, help="scenario name in the file")
    run.add_argument(
        "--scenario_text",
        default="{}",
        help="YAML applied on top of the scenario, e.g. "
        "'{controller: {method: weighted_sum}}'",
    )
    run.add_argument(
        "--duration",
        type=float,
        default=None,
        help="simulated seconds (default: the scenario's)",
    )
    run.add_argument("--no-meshcat", action="store_true", help="no visualization")
    run.add_argument(
        "--html",
        default=None,
        help="where to save the HTML replay (default out/NAME.html)",
    )
    run.add_argument(
        "--graphviz",
        default=None,
        help="write the diagram (.dot, or .svg/.png with pydot)",
    )
    run.add_argument(
        "--realtime_rate",
        type=float,
        default=None,
        help="simulation speed vs. wall clock (default: 1 with "
        "Meshcat so you can watch live, else as fast as possible)",
    )
    run.add_argument(
        "--wait",
        action="store_true",
        help="keep the Meshcat server up after the run (replay it "
        "there) until Enter or Ctrl-C",
    )
    run.set_defaults(func=_Run)

    bench = sub.add_parser("bench", help="measure the controller's speed")
    bench.add_argument(
        "--robot",
        default="ridgeback_ur10",
        choices=["ridgeback_ur10", "stretch3", "all"],
    )
    bench.add_argument("--humans", type=int, default=0)
    bench.add_argument(
        "--predictor", default="orca_kkt", choices=["orca_kkt", "cvmm", "react"]
    )
    bench.add_argument("--steps", type=int, default=100)
    bench.add_argument("--solver", default="rti", choices=["rti", "snopt", "ipopt"])
    bench.add_argument(
        "--rti_iterations",
        type=int,
        default=None,
        help="SQP passes per step (default: 1; 2 with orca_kkt)",
    )
    bench.add_argument(
        "--scenario_text",
        default="",
        help="YAML applied on top of the benchmark scenario, e.g. "
        "'{prediction: {max_neighbors: 9}}'",
    )
    bench.add_argument("--json", default=None, help="write the figures as JSON")
    bench.set_defaults(func=_Bench)

    from sm2ith_drake.experiments.cli import AddExperimentCommands

    AddExperimentCommands(sub)

    from sm2ith_drake.lcm.cli import AddHardwareCommands

    AddHardwareCommands(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = MakeParser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except UserError as e:
        print(f"sm2ith: error: {e}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("sm2ith: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
