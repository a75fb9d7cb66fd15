"""The versions a benchmark ran with, printed in its header: its figures hold for those
(the lock file, constraints.txt, pins them; docs/portability.md §3); and the digest of the
project's own code and shipped files, which names a benchmark's cached runs."""

from __future__ import annotations

import functools
import hashlib
import os
import platform
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import slipstack.lib

__all__ = ["versions_line", "print_versions", "code_digest"]

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


CODE_PARTS = ("lib", "nodes", "messages", "launch", "analysis")


@functools.cache
def code_digest() -> str:
    """12 hex digits over the project's code and shipped files (:data:`CODE_PARTS`: .py and
    .toml, scenes and materials among them): a cached run is reused only by the same code and
    scenes (a cache keyed on a scene's name alone served a scene from before it was changed)."""
    root = Path(slipstack.lib.__file__).parent.parent
    digest = hashlib.sha256()
    for path in sorted(p for part in CODE_PARTS for p in (root / part).rglob("*") if p.suffix in (".py", ".toml")):
        digest.update(str(path.relative_to(root)).encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()[:12]
