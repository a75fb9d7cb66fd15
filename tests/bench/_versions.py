"""The versions a benchmark ran with, printed in its header: its figures hold for those
(the lock file, constraints.txt, pins them; docs/portability.md §3)."""

from __future__ import annotations

import os
import platform
from importlib.metadata import PackageNotFoundError, version

__all__ = ["versions_line", "print_versions"]

PACKAGES = ("numpy", "scipy", "numba", "llvmlite", "pyzmq", "msgpack", "mcap")


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as fh:
            return next((line.split(":", 1)[1].strip() for line in fh if line.startswith("model name")), "?")
    except OSError:
        return platform.processor() or "?"


def versions_line() -> str:
    """``python 3.11.7, numpy 2.4.6, …; AMD EPYC, 2 cores; OPENBLAS_NUM_THREADS=1``."""
    found = []
    for name in PACKAGES:
        try:
            found.append(f"{name} {version(name)}")
        except PackageNotFoundError:
            found.append(f"{name} -")
    threads = os.environ.get("OPENBLAS_NUM_THREADS", "unset")
    return (f"python {platform.python_version()}, {', '.join(found)}; {_cpu_model()}, "
            f"{len(os.sched_getaffinity(0))} cores; OPENBLAS_NUM_THREADS={threads}")


def print_versions() -> None:
    print(f"[versions] {versions_line()}", flush=True)
