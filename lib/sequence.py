"""Sequence gaps: frames or samples missing from numbered streams.

Bus frames carry ``Header.seq`` per publisher and topic
(:func:`slipstack.messages.frame.publisher_key` names the stream); some devices number
their samples (ATI RDT's ``rdt_sequence``). Both are counted by :class:`SeqTracker`.
"""

from __future__ import annotations

from typing import Hashable

__all__ = ["SeqTracker"]


class SeqTracker:
    """Sequence gaps of many streams (a stream: one publisher's frames on one topic).

    ``update`` takes each frame's sequence number in arrival order; a number ahead by
    more than one means frames went missing (``lost``), a number that does not advance
    means the publisher restarted its count (``restarts``; no loss). At most
    ``max_streams`` streams are remembered; the oldest is forgotten first.
    """

    def __init__(self, max_streams: int = 256) -> None:
        self.max_streams = max_streams
        self.lost = 0
        self.restarts = 0
        self._last: dict[Hashable, int] = {}

    def update(self, seq: int, stream: Hashable = None, skipped: int = 0) -> int:
        """Record ``seq`` of ``stream``; returns how many frames went missing just before it.

        ``skipped``: frames of this stream received before this one but not read
        (drained for a newer one); they fill as much of a gap.
        """
        last = self._last.get(stream)
        gap = 0
        if last is None:
            if len(self._last) >= self.max_streams:
                del self._last[next(iter(self._last))]
        elif seq > last + 1 + skipped:
            gap = seq - last - 1 - skipped
            self.lost += gap
        elif seq <= last:
            self.restarts += 1
        self._last[stream] = seq
        return gap

    def forget(self, stream: Hashable = None) -> None:
        """Start ``stream`` afresh: its next number is not compared with the last one."""
        self._last.pop(stream, None)
