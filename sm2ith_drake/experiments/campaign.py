"""Campaigns: a study's runs (cells × methods × seeds), in parallel, into a
tidy CSV, with plots and a report (Section V).

A run is fully described by its RunSpec (scenario file and name, the YAML
overrides of its method, the seed), so any CSV row can be rerun exactly
(``sm2ith replay``). Runs append their row to the CSV as they finish; a
campaign started again skips the runs already in the CSV (resume).
"""

from __future__ import annotations

import csv
import dataclasses
import math
import multiprocessing
import os
import sys
import time
import traceback
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np
from tqdm import tqdm

from sm2ith_drake.experiments.report import MakePlots, WriteReport
from sm2ith_drake.experiments.studies import Study
from sm2ith_drake.run.metrics import CAMPAIGN_METRICS, CampaignRow
from sm2ith_drake.run.simulation import RunSimulation
from sm2ith_drake.scenario_loader import LoadScenario

# Columns that identify a run, before the metrics.
RUN_COLUMNS = [
    "run_id",
    "study",
    "family",
    "robot",
    "humans",
    "method",
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


@dataclasses.dataclass(frozen=True)
class RunSpec:
    study: str
    family: str
    robot: str
    humans: int
    method: str
    seed: int
    scenario_file: str
    scenario: str
    scenario_text: str
    # Simulated-time cap (s); 0: the scenario's own duration.
    duration: float = 0.0

    @property
    def run_id(self) -> str:
        return f"{self.scenario}/{self.method}/seed{self.seed}"


def PlanRuns(
    study: Study,
    *,
    runs: int | None = None,
    only: str | None = None,
    duration: float = 0.0,
) -> list[RunSpec]:
    """The study's runs: every cell × method × seed.

    Args:
        runs: seeds per method and cell (default: each method's own count,
            e.g. 10 for SM²ITH and 5 for the baselines in pick_and_place).
        only: keep the cells whose scenario name contains this text.
        duration: cap on each run's simulated time (0: the scenario's).
    """
    specs = []
    for cell in study.cells:
        if only and only not in cell.scenario:
            continue
        for method in study.methods:
            for seed in range(method.seeds if runs is None else runs):
                specs.append(
                    RunSpec(
                        study=study.name,
                        family=cell.family,
                        robot=cell.robot,
                        humans=cell.humans,
                        method=method.name,
                        seed=seed,
                        scenario_file=cell.scenario_file,
                        scenario=cell.scenario,
                        scenario_text=method.scenario_text,
                        duration=duration,
                    )
                )
    return specs


def ApplySeed(scenario, seed: int):
    """Varies the people reproducibly: each start moves up to 0.2 m, starts
    up to 0.5 s later and walks at 90–110 % of its speed; the sensor noise is
    seeded too. The same seed gives every method the same people."""
    rng = np.random.default_rng(seed)
    humans = []
    for h in scenario.humans:
        humans.append(
            dataclasses.replace(
                h,
                start=list(np.asarray(h.start) + rng.uniform(-0.2, 0.2, 2)),
                start_time=h.start_time + float(rng.uniform(0.0, 0.5)),
                speed=h.speed * float(rng.uniform(0.9, 1.1)),
            )
        )
    return dataclasses.replace(scenario, humans=humans, random_seed=int(seed))


def LoadRunScenario(spec: RunSpec):
    """The Scenario of a run: the cell's scenario, the method's overrides,
    the seed's people."""

    scenario = LoadScenario(
        filename=spec.scenario_file,
        scenario_name=spec.scenario,
        scenario_text=spec.scenario_text,
    )
    return ApplySeed(scenario, spec.seed)


def _ReferencePath(spec: RunSpec, cache_dir: Path):
    """The base path of the same scenario and controller with no people (the
    "optimal path"), computed once per scenario and method and cached."""

    key = f"{spec.scenario}__{spec.method}__{spec.duration:g}".replace("/", "_")
    path = cache_dir / f"{key}.npy"
    if path.exists():
        return np.load(path)
    scenario = LoadScenario(
        filename=spec.scenario_file,
        scenario_name=spec.scenario,
        scenario_text=spec.scenario_text,
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
        elif key in ("success", "collision"):
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
        runs, only, duration: see PlanRuns.
        executor: "local" (a process pool on this machine) or "ray" (a Ray
            cluster; ``address`` as for ``ray.init``, default a local Ray).
        progress: print a progress bar to stderr.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    csv_path = out / f"{study.name}.csv"
    cache = out / "reference_paths"
    specs = PlanRuns(study, runs=runs, only=only, duration=duration)
    if not specs:
        raise ValueError(f"no runs in study '{study.name}' match --only {only!r}")
    _CsvColumns(csv_path)  # a foreign CSV is refused before any run
    finished = {r["run_id"] for r in ReadRows(csv_path) if r.get("status") == "ok"}
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
    wanted = {s.run_id for s in specs}
    rows = [r for r in ReadRows(csv_path) if r["run_id"] in wanted]

    plots = MakePlots(study, rows, out)
    report = WriteReport(study, rows, out, plots, wall_time_s=wall, ran=len(todo))
    return CampaignResult(csv_path, rows, len(todo), skipped, plots, report, wall)


def _Execute(specs, cache, jobs, executor, address):
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
    # Meshcat state).
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=jobs, mp_context=ctx) as pool:
        futures = [pool.submit(RunOne, spec, cache) for spec in specs]
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
