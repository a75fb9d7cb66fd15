"""Every process slipstack starts runs one thread per numerical library (docs/portability.md §2),
unless the user set the library's variable: counted in real processes, by their threads."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from slipstack.nodes.runtime.threads import THREAD_VARIABLES

ENTRIES = ("slipstack.launch.cli", "slipstack.launch.run_node", "slipstack.nodes.recording.writer_process")
"""The modules the slipstack command, a node process and the recording's writer start from."""


def _threads_after_numpy(entry: str, **env: str) -> int:
    """Threads of a fresh interpreter that imported ``entry``, then numpy and scipy.linalg."""
    clean = {k: v for k, v in os.environ.items() if k not in THREAD_VARIABLES}
    code = (f"import {entry}, numpy, scipy.linalg, os; "
            "numpy.ones((64, 64)) @ numpy.ones((64, 64)); print(len(os.listdir('/proc/self/task')))")
    out = subprocess.run([sys.executable, "-c", code], env={**clean, **env}, capture_output=True, text=True,
                         check=True)
    return int(out.stdout)


@pytest.mark.parametrize("entry", ENTRIES)
def test_a_slipstack_process_runs_one_numerical_thread(entry):
    assert _threads_after_numpy(entry) == 1


@pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2, reason="OpenBLAS starts no more threads than cores")
def test_the_users_thread_count_is_kept():
    assert _threads_after_numpy(ENTRIES[0], OPENBLAS_NUM_THREADS="2") > 1
    assert _threads_after_numpy("json") > 1  # without slipstack: one per core (the test would see nothing)
