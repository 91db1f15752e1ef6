"""``sm2ith experiment`` and ``sm2ith replay``."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import yaml

from sm2ith_drake.cli.run import RunCommand
from sm2ith_drake.errors import UserError
from sm2ith_drake.experiments.campaign import ReadRows, RunCampaign
from sm2ith_drake.experiments.findings import WriteFindings
from sm2ith_drake.experiments.people import (
    AS_SCENARIO,
    PEOPLE_MODELS,
    VARIANTS,
    MergeYaml,
)
from sm2ith_drake.experiments.runs import LoadRunScenario, SpecFromRow
from sm2ith_drake.experiments.studies import STUDIES
from sm2ith_drake.scenario import ScenarioError


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
    variants = _List(args.variant, VARIANTS, "--variant")
    people = _List(args.people, PEOPLE_MODELS + (AS_SCENARIO,), "--people")
    try:
        result = RunCampaign(
            STUDIES[args.study],
            args.out,
            jobs=args.jobs,
            runs=args.runs,
            only=args.only,
            duration=args.duration,
            variants=variants,
            people=people,
            scenario_text=args.scenario_text,
            methods=_Methods(args),
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


def _Methods(args):
    """--methods as a tuple (None: all the study's methods)."""
    names = tuple(m.name for m in STUDIES[args.study].methods)
    return _List(args.methods, names, "--methods")


def _List(text, valid, option):
    """A comma-separated option as a tuple (None: the study's default)."""
    if text is None:
        return None
    values = tuple(v.strip() for v in text.split(",") if v.strip())
    bad = [v for v in values if v not in valid]
    if bad or not values:
        raise _UserError(f"{option} takes a comma list of: " + ", ".join(valid))
    return values


def RunScenarioText(row) -> str:
    """A row's full override: its method's and variant's YAML, and the
    people it met (the seed's draw in its people model) with the seed, so
    that ``sm2ith run`` simulates exactly that run."""
    study = STUDIES.get(row.get("study", ""))
    if study is None:
        raise _UserError(f"the row's study {row.get('study')!r} is unknown")
    try:
        scenario = LoadRunScenario(SpecFromRow(study, row))
    except (ValueError, ScenarioError) as e:
        raise _UserError(str(e)) from e
    people = {
        "humans": [dataclasses.asdict(h) for h in scenario.humans],
        "random_seed": scenario.random_seed,
        "prediction": {"max_humans": scenario.prediction.max_humans},
    }
    return MergeYaml(row["scenario_text"], yaml.safe_dump(people))


def _Findings(args) -> int:
    out = Path(args.out)
    rows = {name: ReadRows(out / f"{name}.csv") for name in STUDIES}
    if not any(rows.values()):
        raise _UserError(f"no study CSV in {out}")
    print(f"findings: {WriteFindings(STUDIES, rows, out)}")
    return 0


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
    args.scenario_text = RunScenarioText(row)
    args.seed = None  # the people are in the text
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
        description="Runs a study (cells × variants × people models × "
        "methods × seeds, every method on the same seeds) in parallel, "
        "writes OUT/STUDY.csv (one row per run), OUT/STUDY_VARIANT_PEOPLE.png "
        "(box plots with the medians' 95 % CIs), OUT/STUDY_report.md "
        "(medians and paired differences with bootstrap CIs) and "
        "OUT/findings.md (what holds of the paper's findings). Runs already "
        "in the CSV are skipped, so an interrupted campaign resumes where it "
        "stopped.",
    )
    exp.add_argument("study", help="one of: " + ", ".join(STUDIES))
    exp.add_argument(
        "--runs",
        type=int,
        default=None,
        help="seeds per method and cell, the same for every method "
        "(default: the study's, 10)",
    )
    exp.add_argument(
        "--variant",
        default=None,
        help="safety variants, a comma list of: " + ", ".join(VARIANTS) + " "
        "(paper: the paper's DT-CBF only; safe: the shipped safety "
        "mechanism; default: the study's)",
    )
    exp.add_argument(
        "--people",
        default=None,
        help="people models, a comma list of: "
        + ", ".join(PEOPLE_MODELS + (AS_SCENARIO,))
        + " (the behaviour of every person who walks to goals; scripted "
        "and adversarial people stay; default: the study's)",
    )
    exp.add_argument(
        "--methods",
        default=None,
        help="only these of the study's methods, a comma list (default: "
        "all), e.g. SM2ITH after a change that only SM²ITH's predictor sees; "
        "the others' rows can then be copied in from an earlier CSV",
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
        "--only",
        default=None,
        help="only cells whose name contains this (e.g. doorway_stretch3_5h)",
    )
    exp.add_argument(
        "--duration",
        type=float,
        default=0.0,
        help="cap each run's simulated seconds (0: the scenario's; a capped "
        "run that did not finish counts as a timeout)",
    )
    exp.add_argument(
        "--scenario_text",
        default="",
        help="YAML applied to every run, alike for every method (the method's "
        "and the variant's own settings win), e.g. "
        "'{safety: {guard_gap: 0.1}}'; use a new --out for each",
    )
    exp.set_defaults(func=_Experiment)

    findings = sub.add_parser(
        "findings",
        help="rewrite OUT/findings.md from the study CSVs in OUT",
        description="The 'what holds' table of the paper's findings (a)-(d) "
        "from every study CSV in OUT (written after every campaign too).",
    )
    findings.add_argument("--out", default="out/experiments", help="directory")
    findings.set_defaults(func=_Findings)

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
