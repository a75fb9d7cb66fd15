"""A ``contact`` message seen through the slip tests' contact protocol (pad frame F, SI)."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from slipstack.lib.pad import PadGeometry
from slipstack.messages import Contact

__all__ = ["ContactView", "pad_positions"]

_NO_POSITIONS = np.zeros((0, 2))


@lru_cache(maxsize=8)
def pad_positions(rows: int, cols: int, pitch_m: float) -> np.ndarray:
    """Taxel positions (N, 2) m of a pad, cached per geometry."""
    return PadGeometry(rows, cols, pitch_m).positions


class ContactView:
    """``f_n`` N, ``f_t`` (2,) N, ``tau`` N·m, ``phi`` (N,) N, ``positions`` (N, 2) m.

    Without tactile data (``has_tactile`` false) ``phi`` and ``positions`` are empty,
    so only the F/T tests (with a configured β) can judge it.
    """

    __slots__ = ("f_n", "f_t", "tau", "phi", "positions")

    def __init__(self, msg: Contact) -> None:
        self.f_n = msg.f_n
        self.f_t = msg.f_t
        self.tau = msg.tau
        if msg.has_tactile and msg.phi.size:
            self.phi = msg.phi
            self.positions = pad_positions(msg.rows, msg.cols, msg.pitch_m)
        else:
            self.phi = np.zeros(0)
            self.positions = _NO_POSITIONS
