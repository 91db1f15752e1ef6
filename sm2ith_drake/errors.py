"""Errors shared by the command-line tools."""


class UserError(Exception):
    """An error in the user's input: the ``sm2ith`` command prints it as one
    line and exits with code 2 (no traceback)."""
