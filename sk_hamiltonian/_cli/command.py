"""``main``: the fitting command or a sub-command, with usage errors as exit code 2."""

import sys

from . import fit, model
from .errors import UsageError
from .outputs import OUTPUTS
from .parser import build_parser

#: Exit status after Ctrl-C: 128 + SIGINT, as shells report a process the signal ended.
INTERRUPTED = 130

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
        printing a one-line message to stderr; Ctrl-C raises
        ``SystemExit(130)`` after one line saying which files were written.
    """
    argv = sys.argv[1:] if argv is None else list(argv)
    OUTPUTS.__init__()
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
    except KeyboardInterrupt:
        # A traceback would say where Python was, which the user did not ask;
        # what was written is what they need to know.
        parser.exit(INTERRUPTED, f"{parser.prog}: interrupted; {OUTPUTS.describe()}\n")
