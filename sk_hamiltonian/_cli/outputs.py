"""What the running command has written, so that an interrupt can say so truthfully.

Ctrl-C ends the command with one line (:func:`~.command.main`), which names
the files finished before it and the one being written when it came, which
may be incomplete (the model file never is: it is written beside and renamed,
see :func:`sk_hamiltonian.io.save`).
"""

import contextlib


class Outputs:
    """The files a command has finished writing, and the one it is writing."""

    def __init__(self):
        self.done, self.current = [], None

    @contextlib.contextmanager
    def writing(self, path, atomic=False):
        """Record ``path`` as being written within the block, and as written after it.

        ``atomic``: an interrupt leaves no partial file at ``path``.
        """
        self.current = None if atomic else path
        yield
        self.current = None
        self.done.append(path)

    def describe(self):
        """``"no file written"``, or which files were and which may be incomplete."""
        parts = [f"written: {', '.join(self.done)}"] if self.done else []
        if self.current is not None:
            parts.append(f"{self.current} may be incomplete")
        return "; ".join(parts) or "no file written"


#: The running command's outputs (the command runs once per process; main resets it).
OUTPUTS = Outputs()
