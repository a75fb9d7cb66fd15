"""A progress bar for reading a large file (tqdm), on stderr, when someone is watching.

    with file_progress(path, "bag info") as progress:
        info = recording_info(path, progress=progress)

``progress`` is called with the bytes read so far (the readers call it after each
chunk). The bar is shown only if stderr is a terminal and the file is at least
:data:`PROGRESS_MIN_BYTES` long; otherwise ``progress`` is ``None`` and tqdm is not
even imported (``bag info`` of a small file starts as fast as before).
"""

from __future__ import annotations

import os
import sys
from contextlib import contextmanager
from typing import Callable, Iterator

__all__ = ["file_progress", "PROGRESS_MIN_BYTES"]

PROGRESS_MIN_BYTES = 4 * 1024 * 1024
"""Smaller files are read without a bar (a fraction of a second)."""


@contextmanager
def file_progress(path: str | os.PathLike, label: str) -> Iterator[Callable[[int], None] | None]:
    """A callback ``progress(bytes read)`` drawing a bar for ``path``, or ``None`` (module docstring)."""
    try:
        size = os.path.getsize(path)
    except OSError:
        size = 0
    if size < PROGRESS_MIN_BYTES or not sys.stderr.isatty():
        yield None
        return
    from tqdm import tqdm

    with tqdm(total=size, desc=label, unit="B", unit_scale=True, unit_divisor=1024, file=sys.stderr,
              leave=False, dynamic_ncols=True) as bar:
        def progress(done: int) -> None:
            bar.update(min(done, size) - bar.n)

        yield progress
