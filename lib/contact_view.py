"""A fused contact seen through the slip tests' contact protocol (pad frame F, SI).

:class:`FusedContact` is what fusion produces (the ``contact`` message fits it, and so
does :class:`~slipstack.lib.detector.PadContact` built from a wrench and a pressure
frame); :class:`ContactView` turns it into the arrays the slip tests read
(:class:`~slipstack.lib.slip_tests.ContactLike`), optionally pooled.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Protocol

import numpy as np

from slipstack.lib.pad import PadGeometry

__all__ = ["FusedContact", "ContactView", "pad_positions", "pool_misfit"]

_NO_POSITIONS = np.zeros((0, 2))


class FusedContact(Protocol):
    """One fused contact in the pad frame ``F``.

    ``f_n`` N; ``f_t`` (2,) N; ``tau`` N·m about z through the pad origin; ``phi``
    (rows·cols,) N per taxel (empty without a pressure frame); ``rows``, ``cols`` and
    ``pitch_m`` (m) the pad's; ``has_tactile``: a pressure frame was paired;
    ``status``: the wrench's (``ok``, ``no_contact``, ``stale`` …); ``tactile_status``:
    why no frame was paired, when none was (``ok`` when one was).
    """

    f_n: float
    f_t: np.ndarray
    tau: float
    phi: np.ndarray
    rows: int
    cols: int
    pitch_m: float
    has_tactile: bool
    status: str
    tactile_status: str


@lru_cache(maxsize=8)
def pad_positions(rows: int, cols: int, pitch_m: float, pool: int = 1) -> np.ndarray:
    """Taxel positions (N, 2) m of a pad, pooled ``pool × pool``; cached per geometry."""
    pad = PadGeometry(rows, cols, pitch_m)
    return (pad.pooled(pool) if pool > 1 else pad).positions


def pool_misfit(contact: FusedContact, pool: int) -> str:
    """Why ``pool`` cannot pool this contact's pad (it does not divide both its rows and cols:
    :class:`ContactView` then keeps the full resolution), or "" where it can or the contact
    has no pressure frame; a node learns its pad only from the frames."""
    if pool == 1 or not contact.has_tactile or not (contact.rows % pool or contact.cols % pool):
        return ""
    return (f"pool {pool} does not divide the pad's {contact.rows}x{contact.cols}: its contacts are judged at full "
            "resolution; set pool to a divisor of both (1: off)")


class ContactView:
    """``f_n`` N, ``f_t`` (2,) N, ``tau`` N·m, ``phi`` (N,) N, ``positions`` (N, 2) m.

    Without tactile data (``has_tactile`` false, or a pad pitch that is not > 0: a contact the
    decoder admits but no pad has) ``phi`` and ``positions`` are empty,
    so only the F/T tests (with a configured β) can judge it. With ``pool > 1`` the
    taxels are summed in ``pool × pool`` blocks (``PadGeometry.pool``): the accuracy/
    speed knob measured in ``tests/bench/bench_pooling.py``; a pad it does not divide is
    kept at full resolution (:func:`pool_misfit` says so).
    """

    __slots__ = ("f_n", "f_t", "tau", "phi", "positions")

    def __init__(self, contact: FusedContact, pool: int = 1) -> None:
        self.f_n = contact.f_n
        self.f_t = contact.f_t
        self.tau = contact.tau
        if contact.has_tactile and contact.phi.size and contact.pitch_m > 0.0:  # a pad without a pitch has no geometry
            if pool > 1 and pool_misfit(contact, pool):
                pool = 1
            if pool > 1:
                self.phi = PadGeometry(contact.rows, contact.cols, contact.pitch_m).pool(contact.phi, pool)
            else:
                self.phi = contact.phi
            self.positions = pad_positions(contact.rows, contact.cols, contact.pitch_m, pool)
        else:
            self.phi = np.zeros(0)
            self.positions = _NO_POSITIONS
