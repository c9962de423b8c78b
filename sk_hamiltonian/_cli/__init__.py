"""The ``sk-hamiltonian`` command, one job per module.

- :mod:`.command`: ``main``, which runs the fitting command or a sub-command
  and turns a :class:`~.errors.UsageError` into one line and exit code 2,
  and Ctrl-C into one line and exit code 130 (:mod:`.outputs`: what was
  written by then);
- :mod:`.parser`: the fitting command's options, their help and checks;
- :mod:`.datafiles`: reading trajectories from .npz and .csv files;
- :mod:`.data`: what the command fits (the built-in example or a file);
- :mod:`.search`: the cross-validated search, behind :func:`.search.run_search`;
- :mod:`.report`: the printed report; :mod:`.figure`: report.png;
- :mod:`.fit`: the fitting command from the options to the model file;
- :mod:`.model`: the ``show`` and ``simulate`` sub-commands.
"""

from .command import main

__all__ = ["main"]
