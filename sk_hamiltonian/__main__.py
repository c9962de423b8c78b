"""The ``sk-hamiltonian`` command: cross-validated Hamiltonian learning in one call.

Run ``sk-hamiltonian --help`` (or ``python -m sk_hamiltonian --help``). The
command lives in :mod:`sk_hamiltonian._cli`; this module is its entry point.
"""

import sys

from ._cli import main

__all__ = ["main"]

if __name__ == "__main__":
    sys.exit(main())
