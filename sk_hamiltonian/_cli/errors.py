"""The command's error: a problem with the command line or the user's file."""

import math


class UsageError(Exception):
    """A problem with the command line or the user's file: one line, exit code 2."""


def check_positive(option, value):
    """Refuse a value of ``option`` that is not a positive finite number (None passes)."""
    if value is not None and not (math.isfinite(value) and value > 0):
        raise UsageError(f"{option} must be a positive finite number; got {value:g}")
