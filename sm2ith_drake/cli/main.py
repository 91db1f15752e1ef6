"""The ``sm2ith`` command line: run | bench | experiment | replay | hardware |
driver.

Errors a user can cause (missing file, unknown scenario, malformed YAML, an
unknown key, a bad value) print one line and exit with code 2, without a
traceback.
"""

from __future__ import annotations

import argparse
import sys

from sm2ith_drake.cli.bench import AddBenchCommand
from sm2ith_drake.cli.experiment import AddExperimentCommands
from sm2ith_drake.cli.hardware import AddHardwareCommands
from sm2ith_drake.cli.run import AddRunCommand
from sm2ith_drake.errors import UserError

EXIT_USAGE = 2


def MakeParser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="sm2ith",
        description="SM2ITH mobile manipulation among people (Drake).",
    )
    sub = parser.add_subparsers(dest="command", required=True)
    AddRunCommand(sub)
    AddBenchCommand(sub)
    AddExperimentCommands(sub)
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
