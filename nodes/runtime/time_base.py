"""One time base for a graph over several machines: the reference machine's clock.

Every stamp of the graph is ``CLOCK_MONOTONIC`` in nanoseconds, and nodes judge ages
by comparing stamps with their own clock (the grip controller holds on inputs older
than its ``timeout_ms``). On one computer that is one clock. Across machines the
launcher of every machine but the first (the *reference*) measures its clock's offset
to the reference (``lib/clock_offset.py``) before it starts a node, and hands it to its
node processes in ``$SLIPSTACK_CLOCK_OFFSET_NS``: their clock is then the local
monotonic clock plus that offset, the reference machine's time (up to the reported
uncertainty). The offset stays fixed for the launch, so the processes of one machine
agree with each other; the launcher keeps measuring and warns when the clocks drift
apart by more than the controller tolerates. A tool started outside the launch (``bag
record``, ``bag play``, ``topic pub``, ``topic hz``) reads the offset from ``graph.json``
(``graph_info.time_base_clock``) and runs on the same clock: the process executor takes
it as its ``clock``.
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
