"""Counted nouns for the command's lines: "1 candidate", "2 candidates"."""


def counted(n, singular, plural=None):
    """``n`` and the noun that agrees with it (``plural`` defaults to ``singular + "s"``)."""
    return f"{n} {singular if n == 1 else (plural or singular + 's')}"
