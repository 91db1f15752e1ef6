"""Campaigns: a study's runs (cells × variants × people models × methods ×
seeds), in parallel, into a tidy CSV, with plots and a report (Section V).

A run is fully described by its RunSpec (scenario file and name, the YAML
overrides of its method and variant, the people model, the seed), so any
CSV row can be rerun exactly (``sm2ith replay``). Runs append their row to
the CSV as they finish; a campaign started again skips the runs already in
the CSV (resume).
"""

from __future__ import annotations

import csv
import dataclasses
import datetime
import hashlib
import json
import math
import multiprocessing
import os
import sys
import time
import traceback
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np
import yaml
from tqdm import tqdm

from sm2ith_drake.control.rti_solver import QpSettings
from sm2ith_drake.experiments.findings import WriteFindings
from sm2ith_drake.experiments.people import (
    AS_SCENARIO,
    PEOPLE_MODELS,
    VARIANTS,
    ApplySeed,
    MergeYaml,
)
from sm2ith_drake.experiments.report import MakePlots, WriteReport
from sm2ith_drake.experiments.runs import LoadRunScenario, PlanRuns, RunSpec
from sm2ith_drake.experiments.studies import STUDIES, Study
from sm2ith_drake.run.metrics import BOOLEAN_METRICS, CAMPAIGN_METRICS, CampaignRow
from sm2ith_drake.run.simulation import RunSimulation
from sm2ith_drake.scenario_loader import LoadScenario

# Re-exported: sm2ith run applies a replayed row's seed with ApplySeed.
__all__ = ["ApplySeed", "LoadRunScenario", "PlanRuns", "RunSpec", "RunCampaign"]

# Columns that identify a run, before the metrics.
RUN_COLUMNS = [
    "run_id",
    "study",
    "family",
    "robot",
    "humans",
    "method",
    "variant",
    "people",
    "seed",
    "scenario_file",
    "scenario",
    "scenario_text",
    "duration",
    "status",
    "error",
    "wall_time_s",
]
COLUMNS = RUN_COLUMNS + CAMPAIGN_METRICS


def _ReferencePath(spec: RunSpec, cache_dir: Path):
    """The "optimal path": the base path of the same scenario and controller
    with no people, computed once per scenario, controller and variant and
    cached. Without people the predictors have nobody to predict, so the
    method's prediction override is left out: SM²ITH, CVMM and React share
    one reference (the weighted sum, another controller, has its own)."""

    overrides = yaml.safe_load(spec.scenario_text or "{}") or {}
    overrides.pop("prediction", None)
    text = MergeYaml(yaml.safe_dump(overrides)) if overrides else ""
    key = f"{spec.scenario_file}|{spec.scenario}|{text}|{spec.duration:g}"
    digest = hashlib.sha1(key.encode()).hexdigest()[:10]
    path = cache_dir / f"{spec.scenario}__{digest}.npy"
    if path.exists():
        return np.load(path)
    scenario = LoadScenario(
        filename=spec.scenario_file, scenario_name=spec.scenario, scenario_text=text
    )
    scenario = dataclasses.replace(scenario, humans=[])
    result = RunSimulation(
        scenario, duration=spec.duration or None, stop_when_done=True
    )
    xy = np.asarray(result.log.states)[:, :2]
    cache_dir.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(f".{os.getpid()}.tmp.npy")
    np.save(tmp, xy)
    os.replace(tmp, path)  # atomic: parallel workers may race here
    return xy


def RunOne(spec: RunSpec, cache_dir: str) -> dict:
    """Runs one campaign run and returns its CSV row. Never raises: a failed
    run returns status "error" with the message."""

    row = {k: getattr(spec, k, "") for k in RUN_COLUMNS if hasattr(spec, k)}
    row["run_id"] = spec.run_id
    start = time.perf_counter()
    try:
        reference = _ReferencePath(spec, Path(cache_dir))
        scenario = LoadRunScenario(spec)
        result = RunSimulation(
            scenario, duration=spec.duration or None, stop_when_done=True
        )
        robot = result.diagram.GetSubsystemByName("controller").controller.robot
        row.update(CampaignRow(result.log, robot, scenario, result.metrics, reference))
        row["status"], row["error"] = "ok", ""
    except Exception as e:  # noqa: BLE001 — a campaign outlives a bad run
        row["status"] = "error"
        row["error"] = f"{type(e).__name__}: {e}".replace("\n", " ")[:500]
        traceback.print_exc(file=sys.stderr)
    row["wall_time_s"] = round(time.perf_counter() - start, 3)
    return row


def ReadRows(csv_path: Path) -> list[dict]:
    """The CSV's rows (the last row per run_id wins), values parsed."""
    if not Path(csv_path).exists():
        return []
    rows: dict = {}
    with open(csv_path, newline="") as f:
        for raw in csv.DictReader(f):
            rows[raw["run_id"]] = _Parse(raw)
    return list(rows.values())


def _Parse(raw: dict) -> dict:
    out = {}
    for key, value in raw.items():
        if key in ("humans", "seed"):
            out[key] = int(value)
        elif key in BOOLEAN_METRICS:
            out[key] = value == "True" if value in ("True", "False") else math.nan
        elif key in CAMPAIGN_METRICS or key in ("wall_time_s", "duration"):
            try:
                out[key] = float(value)
            except ValueError:
                out[key] = math.nan
        else:
            out[key] = value
    return out


def _CsvColumns(csv_path: Path) -> list:
    """The columns to append with: the file's own order if it has exactly
    ours (a CSV from an older version may order them differently)."""
    if not csv_path.exists():
        return COLUMNS
    with open(csv_path, newline="") as f:
        header = next(csv.reader(f), [])
    if sorted(header) != sorted(COLUMNS):
        raise ValueError(
            f"{csv_path} has other columns than this version writes; "
            "resume it with the version that wrote it or use a new --out"
        )
    return header


def _AppendRow(csv_path: Path, row: dict) -> None:
    fieldnames = _CsvColumns(csv_path)
    new = not csv_path.exists()
    with open(csv_path, "a", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=fieldnames, extrasaction="ignore")
        if new:
            writer.writeheader()
        writer.writerow({k: _Format(row.get(k, "")) for k in COLUMNS})


def _Format(value):
    if isinstance(value, float) and not isinstance(value, bool):
        return "nan" if math.isnan(value) else f"{value:.6g}"
    return value


@dataclasses.dataclass
class CampaignResult:
    csv_path: Path
    rows: list
    ran: int
    skipped: int
    plots: list
    report: Path
    wall_time_s: float


def RunCampaign(
    study: Study,
    out_dir,
    *,
    jobs: int = 1,
    runs: int | None = None,
    only: str | None = None,
    duration: float = 0.0,
    variants: tuple | list | None = None,
    people: tuple | list | None = None,
    scenario_text: str = "",
    methods: tuple | list | None = None,
    executor: str = "local",
    address: str | None = None,
    progress: bool = True,
) -> CampaignResult:
    """Runs (or resumes) a study and writes ``<out_dir>/<study>.csv``, the
    plots and ``<out_dir>/<study>_report.md``.

    Args:
        study: the Study.
        out_dir: the output directory (created).
        jobs: parallel processes (local executor).
        runs, only, duration, variants, people, methods: see PlanRuns.
        executor: "local" (a process pool on this machine) or "ray" (a Ray
            cluster; ``address`` as for ``ray.init``, default a local Ray).
        progress: print a progress bar to stderr.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    csv_path = out / f"{study.name}.csv"
    cache = out / "reference_paths"
    specs = PlanRuns(
        study,
        runs=runs,
        only=only,
        duration=duration,
        variants=variants,
        people=people,
        scenario_text=scenario_text,
        methods=methods,
    )
    if not specs:
        raise ValueError(f"no runs in study '{study.name}' match --only {only!r}")
    if scenario_text:
        try:  # a bad override is refused before any run
            scenario = LoadRunScenario(specs[0])
            QpSettings(scenario.controller.solver_options)
        except Exception as e:  # noqa: BLE001 (ScenarioError, UserError, YAML)
            raise ValueError(f"--scenario_text: {e}") from e
    _CsvColumns(csv_path)  # a foreign CSV is refused before any run
    done = {r["run_id"]: r for r in ReadRows(csv_path) if r.get("status") == "ok"}
    for spec in specs:
        row = done.get(spec.run_id)
        if row is not None and row.get("scenario_text", "") != spec.scenario_text:
            raise ValueError(
                f"{csv_path} already has run {spec.run_id} with other overrides "
                f"({row.get('scenario_text')!r}, not {spec.scenario_text!r}); "
                "use another --out"
            )
    finished = set(done)
    todo = [s for s in specs if s.run_id not in finished]
    skipped = len(specs) - len(todo)
    if progress:
        print(
            f"study {study.name}: {len(specs)} runs, {skipped} already in "
            f"{csv_path} (skipped), {len(todo)} to run with "
            f"{jobs if executor == 'local' else 'ray'} worker(s)",
            file=sys.stderr,
        )
    failed = 0
    start = time.perf_counter()
    with tqdm(
        total=len(todo), unit="run", file=sys.stderr, disable=not progress
    ) as bar:
        for row in _Execute(todo, str(cache), jobs, executor, address):
            _AppendRow(csv_path, row)
            failed += row.get("status") != "ok"
            bar.set_postfix_str(
                f"{failed} failed | {row['run_id']} {row.get('status')} "
                f"{row.get('wall_time_s', 0):.1f}s"
            )
            bar.update()
    wall = time.perf_counter() - start
    total = _RecordWallTime(out / f"{study.name}_timing.json", wall, len(todo), jobs)
    # The report covers these cells and seeds in every variant and people
    # model the CSV has (a study may be run one axis value at a time).
    wanted = {
        s.run_id
        for s in PlanRuns(
            study,
            runs=runs,
            only=only,
            duration=duration,
            variants=VARIANTS,
            people=PEOPLE_MODELS + (AS_SCENARIO,),
            scenario_text=scenario_text,
        )
    }
    rows = [r for r in ReadRows(csv_path) if r["run_id"] in wanted]

    plots = MakePlots(study, rows, out)
    report = WriteReport(
        study,
        rows,
        out,
        plots,
        wall_time_s=wall,
        ran=len(todo),
        study_wall_time_s=total,
    )
    WriteFindings(
        STUDIES,
        {name: ReadRows(out / f"{name}.csv") for name in STUDIES},
        out,
    )
    return CampaignResult(csv_path, rows, len(todo), skipped, plots, report, wall)


def _RecordWallTime(path: Path, wall: float, ran: int, jobs: int) -> float:
    """Appends this invocation to the study's timing file; returns the
    study's wall time over every invocation that ran something."""
    record = json.loads(path.read_text()) if path.exists() else []
    if ran:
        record.append(
            {
                "date": datetime.datetime.now().isoformat(timespec="seconds"),
                "runs": ran,
                "jobs": jobs,
                "wall_time_s": round(wall, 1),
            }
        )
        path.write_text(json.dumps(record, indent=1) + "\n")
    return float(sum(r["wall_time_s"] for r in record))


# Runs per worker before a local pool is replaced by a fresh one: pydrake
# keeps a finished run's Python systems alive (reference cycles through
# C++), ~16 MB a run, so a worker that ran the doorway study's 720 runs
# would hold ~11 GB. A new pool every RUNS_PER_WORKER × jobs runs keeps a
# worker under ~2 GB. (Not ProcessPoolExecutor's max_tasks_per_child: on
# Python 3.12.1 that pool hung once its first workers retired.)
RUNS_PER_WORKER = 120


def _Execute(specs, cache, jobs, executor, address, runs_per_worker=None):
    """Yields rows as runs finish."""
    if not specs:
        return
    if executor == "ray":
        yield from _ExecuteRay(specs, cache, address)
        return
    if executor != "local":
        raise ValueError(f"--executor must be local|ray, got {executor!r}")
    if jobs <= 1:
        for spec in specs:
            yield RunOne(spec, cache)
        return
    # "spawn": every worker starts a clean interpreter (no forked solver or
    # Meshcat state); a pool per chunk of runs (RUNS_PER_WORKER).
    ctx = multiprocessing.get_context("spawn")
    chunk = jobs * (runs_per_worker or RUNS_PER_WORKER)
    for first in range(0, len(specs), chunk):
        with ProcessPoolExecutor(max_workers=jobs, mp_context=ctx) as pool:
            batch = specs[first : first + chunk]
            futures = [pool.submit(RunOne, spec, cache) for spec in batch]
            for future in as_completed(futures):
                yield future.result()


def _ExecuteRay(specs, cache, address):
    try:
        import ray
    except ImportError as e:
        raise RuntimeError(
            "--executor ray needs Ray: pip install 'sm2ith-drake[ray]'"
        ) from e
    started = not ray.is_initialized()
    if started:
        ray.init(address=address, include_dashboard=False, log_to_driver=False)
    try:
        remote = ray.remote(num_cpus=1)(RunOne)
        pending = [remote.remote(spec, cache) for spec in specs]
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            for ref in done:
                yield ray.get(ref)
    finally:
        if started:
            ray.shutdown()
