"""A ``contact`` message seen through the slip tests' contact protocol (pad frame F, SI)."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from slipstack.lib.pad import PadGeometry
from slipstack.messages import Contact

__all__ = ["ContactView", "pad_positions"]

_NO_POSITIONS = np.zeros((0, 2))


@lru_cache(maxsize=8)
def pad_positions(rows: int, cols: int, pitch_m: float, pool: int = 1) -> np.ndarray:
    """Taxel positions (N, 2) m of a pad, pooled ``pool × pool``; cached per geometry."""
    pad = PadGeometry(rows, cols, pitch_m)
    return (pad.pooled(pool) if pool > 1 else pad).positions


class ContactView:
    """``f_n`` N, ``f_t`` (2,) N, ``tau`` N·m, ``phi`` (N,) N, ``positions`` (N, 2) m.

    Without tactile data (``has_tactile`` false) ``phi`` and ``positions`` are empty,
    so only the F/T tests (with a configured β) can judge it. With ``pool > 1`` the
    taxels are summed in ``pool × pool`` blocks (``PadGeometry.pool``): the accuracy/
    speed knob measured in ``tests/bench/bench_pooling.py``.
    """

    __slots__ = ("f_n", "f_t", "tau", "phi", "positions")

    def __init__(self, msg: Contact, pool: int = 1) -> None:
        self.f_n = msg.f_n
        self.f_t = msg.f_t
        self.tau = msg.tau
        if msg.has_tactile and msg.phi.size:
            if pool > 1:
                self.phi = PadGeometry(msg.rows, msg.cols, msg.pitch_m).pool(msg.phi, pool)
            else:
                self.phi = msg.phi
            self.positions = pad_positions(msg.rows, msg.cols, msg.pitch_m, pool)
        else:
            self.phi = np.zeros(0)
            self.positions = _NO_POSITIONS
