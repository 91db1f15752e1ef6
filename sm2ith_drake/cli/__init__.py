"""The ``sm2ith`` command (see :mod:`sm2ith_drake.cli.main`)."""

from sm2ith_drake.cli.main import EXIT_USAGE, MakeParser, main

__all__ = ["EXIT_USAGE", "MakeParser", "main"]
