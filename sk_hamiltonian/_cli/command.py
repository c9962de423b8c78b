"""``main``: the fitting command or a sub-command, with usage errors as exit code 2."""

import sys

from . import fit, model
from .errors import UsageError
from .parser import build_parser

SUBCOMMANDS = {"show": model.show, "simulate": model.simulate}


def main(argv=None):
    """Run the command.

    Parameters
    ----------
    argv : list of str, default=None
        Arguments; None reads ``sys.argv``.

    Returns
    -------
    status : int
        0 on success. Usage and data errors raise ``SystemExit(2)`` after
        printing a one-line message to stderr.
    """
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser()
    if argv and argv[0] in SUBCOMMANDS:
        command = SUBCOMMANDS[argv[0]]
        run = lambda: command(argv[1:])  # noqa: E731
    else:
        args = parser.parse_args(argv)
        run = lambda: fit.run(args)  # noqa: E731
    try:
        return run()
    except UsageError as error:
        parser.exit(2, f"{parser.prog}: error: {error}\n")
