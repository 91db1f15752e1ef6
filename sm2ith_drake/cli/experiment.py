"""``sm2ith experiment`` and ``sm2ith replay``."""

from __future__ import annotations

from pathlib import Path

from sm2ith_drake.cli.run import RunCommand
from sm2ith_drake.errors import UserError
from sm2ith_drake.experiments.campaign import ReadRows, RunCampaign
from sm2ith_drake.experiments.studies import STUDIES


def _UserError(message):

    return UserError(message)


def _Experiment(args) -> int:

    if args.study not in STUDIES:
        raise _UserError(
            f"unknown study '{args.study}'; studies: " + ", ".join(STUDIES)
        )
    if args.jobs < 1 or (args.runs is not None and args.runs < 1):
        raise _UserError("--jobs and --runs must be ≥ 1")
    if args.duration < 0:
        raise _UserError("--duration must be ≥ 0")
    if args.address and args.executor != "ray":
        raise _UserError("--address is for --executor ray")
    try:
        result = RunCampaign(
            STUDIES[args.study],
            args.out,
            jobs=args.jobs,
            runs=args.runs,
            only=args.only,
            duration=args.duration,
            executor=args.executor,
            address=args.address,
        )
    except ValueError as e:
        raise _UserError(str(e)) from e
    except RuntimeError as e:
        raise _UserError(str(e)) from e
    failed = sum(r.get("status") != "ok" for r in result.rows)
    print(
        f"{args.study}: {len(result.rows)} runs in {result.csv_path} "
        f"({result.ran} run now in {result.wall_time_s / 60:.1f} min, "
        f"{result.skipped} skipped as already done, {failed} failed to run)"
    )
    for plot in result.plots:
        print(f"plot:   {plot}")
    print(f"report: {result.report}")
    return 1 if failed else 0


def _Replay(args) -> int:

    csv_path = Path(args.csv)
    if not csv_path.exists():
        raise _UserError(f"no such CSV: {csv_path}")
    rows = ReadRows(csv_path)
    if not rows:
        raise _UserError(f"{csv_path} has no runs")
    row = next((r for r in rows if r["run_id"] == args.row), None)
    if row is None:
        try:
            row = rows[int(args.row)]
        except (ValueError, IndexError):
            raise _UserError(
                f"ROW must be a run_id or an index 0..{len(rows) - 1}, got {args.row!r}"
            ) from None
    print(f"replaying {row['run_id']} (seed {row['seed']})")
    args.file = row["scenario_file"]
    args.scenario = row["scenario"]
    args.scenario_text = row["scenario_text"]
    args.seed = int(row["seed"])
    duration = float(row.get("duration") or 0.0)
    args.duration = duration if duration > 0 else None
    args.graphviz = None
    args.stop_when_done = True
    return RunCommand(args)


def AddExperimentCommands(sub) -> None:
    """Registers ``experiment`` and ``replay`` on the ``sm2ith`` parser."""

    exp = sub.add_parser(
        "experiment",
        help="run one of the paper's studies as a campaign",
        description="Runs a study (cells × methods × seeds) in parallel, "
        "writes OUT/STUDY.csv (one row per run), OUT/STUDY.png (box plots) "
        "and OUT/STUDY_report.md. Runs already in the CSV are skipped, so an "
        "interrupted campaign resumes where it stopped.",
    )
    exp.add_argument("study", help="one of: " + ", ".join(STUDIES))
    exp.add_argument(
        "--runs",
        type=int,
        default=None,
        help="seeds per method and scenario (default: the study's, e.g. "
        "10 for SM2ITH and 5 for the baselines)",
    )
    exp.add_argument("--jobs", type=int, default=2, help="parallel processes")
    exp.add_argument("--out", default="out/experiments", help="output directory")
    exp.add_argument(
        "--executor",
        default="local",
        choices=["local", "ray"],
        help="local processes, or a Ray cluster (pip install sm2ith-drake[ray])",
    )
    exp.add_argument(
        "--address", default=None, help="Ray cluster address (default: local Ray)"
    )
    exp.add_argument(
        "--only", default=None, help="only scenarios whose name contains this"
    )
    exp.add_argument(
        "--duration",
        type=float,
        default=0.0,
        help="cap each run's simulated seconds (0: the scenario's; a capped "
        "run that did not finish counts as a timeout)",
    )
    exp.set_defaults(func=_Experiment)

    replay = sub.add_parser(
        "replay", help="rerun one campaign run with Meshcat and save its replay"
    )
    replay.add_argument("csv", help="a campaign CSV (sm2ith experiment)")
    replay.add_argument("row", help="the row's run_id, or its 0-based index")
    replay.add_argument("--no-meshcat", action="store_true")
    replay.add_argument("--html", default=None, help="where to save the replay")
    replay.add_argument(
        "--realtime_rate", type=float, default=None, help="as for sm2ith run"
    )
    replay.add_argument("--wait", action="store_true", help="as for sm2ith run")
    replay.set_defaults(func=_Replay)
