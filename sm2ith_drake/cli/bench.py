"""``sm2ith bench``: measure the controller's speed."""

from __future__ import annotations

import json
from pathlib import Path

from sm2ith_drake.control.profiling import STEP
from sm2ith_drake.errors import UserError
from sm2ith_drake.run.bench import RunBenchmark


def _Bench(args) -> int:
    robots = ["ridgeback_ur10", "stretch3"] if args.robot == "all" else [args.robot]
    if args.repeat < 1:
        raise UserError("--repeat must be ≥ 1")
    results = []
    # Rounds of every robot in turn, so that a drift of the machine's speed
    # falls on every robot alike.
    for run in range(args.repeat):
        for robot in robots:
            r = RunBenchmark(
                robot=robot,
                humans=args.humans,
                predictor=args.predictor,
                steps=args.steps,
                solver=args.solver,
                rti_iterations=args.rti_iterations,
                scenario_text=args.scenario_text,
                profile=args.profile,
            )
            if args.repeat > 1:
                r["run"] = run + 1
            results.append(r)
            _PrintRun(r)
            if args.profile:
                _PrintProfile(r)
    if args.repeat > 1:
        for robot in robots:
            _PrintSpread(robot, [r for r in results if r["robot"] == robot])
    if args.json:
        Path(args.json).write_text(
            json.dumps(results[0] if len(results) == 1 else results, indent=2)
        )
        print(f"wrote {args.json}")
    return 0


def _PrintRun(r: dict) -> None:
    iters = r["mean_iterations"]
    iters = "n/a" if iters is None else f"{iters:.1f}"
    run = f" run {r['run']}" if "run" in r else ""
    print(
        f"{r['robot']:15s} solver={r['solver']} qp={r['qp_solver']} "
        f"steps={r['steps']}{run}  "
        f"median {r['median_ms']:.1f} ms  p95 {r['p95_ms']:.1f} ms  "
        f"p99 {r['p99_ms']:.1f} ms  max {r['max_ms']:.1f} ms  "
        f"first step {r['first_step_ms']:.1f} ms  setup {r['setup_ms']:.0f} ms  "
        f"mean iterations {iters}  "
        f"failures {r['solver_failures']}  fallbacks {r['fallbacks']}  "
        f"solved through {r['solved_through']}"
    )


def _PrintSpread(robot: str, runs: list[dict]) -> None:
    """The run-to-run spread (lowest–highest) of one robot's runs. The plans
    are deterministic: runs with other mean iterations are flagged."""
    spread = "  ".join(
        f"{label} {min(r[key] for r in runs):.1f}–{max(r[key] for r in runs):.1f} ms"
        for label, key in (
            ("median", "median_ms"),
            ("p99", "p99_ms"),
            ("max", "max_ms"),
            ("first step", "first_step_ms"),
        )
    )
    iterations = {r["mean_iterations"] for r in runs}
    plans = "the same plans" if len(iterations) == 1 else "DIFFERENT plans"
    failures = sum(r["solver_failures"] for r in runs)
    fallbacks = sum(r["fallbacks"] for r in runs)
    print(
        f"{robot:15s} over {len(runs)} runs: {spread}  ({plans}; failures "
        f"{failures}, fallbacks {fallbacks} in all)"
    )


def _PrintProfile(r: dict) -> None:
    """The phase table: median ms per control instant, exclusive of the
    phases nested inside (they add up to the instant), and inclusive."""
    profile, inclusive = r["profile"], r["profile_inclusive"]
    calls = r["profile_calls"]
    total = profile[STEP]
    print(
        f"  profile over {r['steps']} control instants (median per instant; "
        f"'self' excludes nested phases, 'incl' includes them)"
    )
    header = f"{'self ms':>8s} {'share':>6s} {'incl ms':>8s} {'calls':>6s}"
    print(f"  {'phase':34s} {header}")
    for name, ms in profile.items():
        share = f"{100 * ms / total:5.1f}%" if total > 0 else "   n/a"
        incl = inclusive.get(name)
        incl = f"{incl:8.2f}" if incl is not None else " " * 8
        n = calls.get(name)
        n = f"{n:6.1f}" if n is not None else " " * 6
        print(f"  {name:34s} {ms:8.2f} {share} {incl} {n}")


def AddBenchCommand(sub) -> None:
    bench = sub.add_parser("bench", help="measure the controller's speed")
    bench.add_argument(
        "--robot",
        default="ridgeback_ur10",
        choices=["ridgeback_ur10", "stretch3", "all"],
        help="the robot, or both in turn (default: ridgeback_ur10)",
    )
    bench.add_argument(
        "--humans",
        type=int,
        default=0,
        help="people pacing across the robot's way (default: 0)",
    )
    bench.add_argument(
        "--predictor", default="orca_kkt", choices=["orca_kkt", "cvmm", "react"]
    )
    bench.add_argument(
        "--steps", type=int, default=100, help="control steps timed (default: 100)"
    )
    bench.add_argument(
        "--repeat",
        type=int,
        default=1,
        help="runs per robot, in rounds of every robot in turn; prints the "
        "run-to-run spread (default: 1). Runs after the first reuse what it "
        "loaded: their setup and first step are warm",
    )
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
    bench.add_argument(
        "--profile",
        action="store_true",
        help="time the phases of every control instant and print the median "
        "ms per phase (also in --json as 'profile')",
    )
    bench.add_argument("--json", default=None, help="write the figures as JSON")
    bench.set_defaults(func=_Bench)
