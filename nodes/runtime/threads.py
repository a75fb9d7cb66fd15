"""One thread per numerical library in every slipstack process, unless the user says otherwise.

Each node does small array work per message; a BLAS or OpenMP pool of one thread per
core only spins beside it (a lock-step run on 16 cores took twice its CPU). The pools
are sized when their library loads, so this runs before numpy does (the ``launch`` and
``nodes`` packages call it first); a variable the user has set is kept
(docs/portability.md §2).
"""

from __future__ import annotations

import os

__all__ = ["THREAD_VARIABLES", "one_thread_per_library"]

THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")
"""The pool sizes of numpy's and scipy's OpenBLAS, OpenMP, MKL and numba's parallel kernels."""


def one_thread_per_library() -> None:
    """Set each of :data:`THREAD_VARIABLES` to 1 where it is not set (children inherit it)."""
    for name in THREAD_VARIABLES:
        os.environ.setdefault(name, "1")
