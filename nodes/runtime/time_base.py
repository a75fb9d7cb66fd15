"""One time base for a graph over several machines: the reference machine's clock.

More in docs/modules.md, `nodes/runtime/time_base.py`.
"""

from __future__ import annotations

import os
import time
from typing import Callable

from slipstack.lib.errors import ConfigError

__all__ = ["CLOCK_OFFSET_ENV", "graph_clock", "shifted_clock"]

CLOCK_OFFSET_ENV = "SLIPSTACK_CLOCK_OFFSET_NS"


def graph_clock() -> Callable[[], int]:
    """The clock (ns) of this process's nodes: ``time.monotonic_ns`` shifted by ``$SLIPSTACK_CLOCK_OFFSET_NS``.

    Raises:
        ConfigError: the variable is set but not an integer.
    """
    text = os.environ.get(CLOCK_OFFSET_ENV, "").strip()
    try:
        offset = int(text) if text else 0
    except ValueError:
        raise ConfigError(f"${CLOCK_OFFSET_ENV} must be an integer number of nanoseconds; got {text!r} "
                          "(the launcher sets it; unset it to run on this machine's clock)") from None
    return shifted_clock(offset)


def shifted_clock(offset_ns: int) -> Callable[[], int]:
    """``time.monotonic_ns`` plus ``offset_ns`` (itself if 0): a machine's clock on the graph's time base."""
    if not offset_ns:
        return time.monotonic_ns

    def shifted() -> int:
        return time.monotonic_ns() + offset_ns

    return shifted
