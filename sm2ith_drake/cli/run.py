"""``sm2ith run``: simulate a named scenario."""

from __future__ import annotations

import sys
from pathlib import Path

from pydrake.geometry import Meshcat

from sm2ith_drake.diagrams.simulation import MakeSimulation
from sm2ith_drake.errors import UserError
from sm2ith_drake.experiments.campaign import ApplySeed
from sm2ith_drake.run.metrics import FormatMetrics
from sm2ith_drake.run.simulation import RunSimulation
from sm2ith_drake.scenario import ScenarioError
from sm2ith_drake.scenario_loader import LoadScenarioAndRobot


def LoadScenarioOrExit(filename: str, name: str, text: str):

    try:
        scenario, _ = LoadScenarioAndRobot(
            filename=filename, scenario_name=name, scenario_text=text
        )
    except (FileNotFoundError, ScenarioError) as e:
        raise UserError(str(e)) from e
    return scenario


def RunCommand(args) -> int:

    scenario = LoadScenarioOrExit(args.file, args.scenario, args.scenario_text)
    if getattr(args, "seed", None) is not None:  # sm2ith replay
        scenario = ApplySeed(scenario, args.seed)
    if args.graphviz:
        diagram = MakeSimulation(scenario=scenario)
        _WriteGraphviz(diagram, args.graphviz)
        print(f"wrote {args.graphviz}")
    meshcat = None
    html = args.html
    if not args.no_meshcat:
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


def AddRunCommand(sub) -> None:
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
    run.set_defaults(func=RunCommand)
