"""Text from a model file, made safe to print on a terminal.

Strings in a model file (provenance, state names, version fields) are data
from wherever the file came from. Printed raw, control characters in them
could move the cursor, clear the screen, retitle the terminal window or
reorder the text (bidirectional overrides), and a newline in one would
start a line that looks like another field. :func:`printable` shows each
such character as its Python escape (``\\x1b``, ``\\u202e``, ``\\n``)
instead, and :func:`escaping_output` applies it to everything a function
prints (but the newlines that end its lines).
"""

import contextlib
import functools
import sys


def printable(text, *, keep_newline=True):
    """``text`` with every non-printable character but the newline escaped.

    Parameters
    ----------
    text : str
        Any text.
    keep_newline : bool, default=True
        Whether ``"\\n"`` passes as it is: yes for a whole output, whose
        lines end with it; no for one value from a file, printed on one line
        of its own, where a newline would start a line that looks like
        another field.

    Returns
    -------
    text : str
        The same text, each control, format or separator character (but
        ``"\\n"`` with ``keep_newline``) replaced by its escape, e.g.
        ``"\\x1b"`` by the four characters ``\\x1b``.

    Examples
    --------
    >>> print(printable("red: \\x1b[31m, reversed: \\u202e"))
    red: \\x1b[31m, reversed: \\u202e
    >>> print(printable("one\\ntwo", keep_newline=False))
    one\\ntwo
    """
    if text.isprintable():
        return text
    kept = "\n" if keep_newline else ""
    return "".join(
        c if c.isprintable() or c in kept else c.encode("unicode_escape").decode("ascii")
        for c in text
    )


class _EscapingWriter:
    """A text stream that writes :func:`printable` text to another."""

    def __init__(self, stream):
        self._stream = stream

    def write(self, text):
        return self._stream.write(printable(text))

    def __getattr__(self, name):
        return getattr(self._stream, name)


def escaping_output(function):
    """Decorate ``function`` so that what it prints to stdout passes through :func:`printable`."""

    @functools.wraps(function)
    def wrapper(*args, **kwargs):
        with contextlib.redirect_stdout(_EscapingWriter(sys.stdout)):
            return function(*args, **kwargs)

    return wrapper
