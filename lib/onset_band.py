"""The onset band's edge as a function of how the contact is loaded (docs/math.md §3.4).

A contact lets go at a load factor that depends on its load path and on how its
pressure is spread: a pull on a flat face at γ ≈ 1, a twist or a force on a curved,
slip-weakening tip lower (it slips progressively from its lightly pressed edges). Each
identified onset carries its load path :func:`load_path` and pressure spread
:func:`pressure_spread`; :class:`OnsetBand` gives the edge from the onsets of the same
kind (lib/material.py's prediction bound, on them alone), and the bound over all onsets
where its onsets carry no load path, and the worst case (the sliding level) for a load path
none of them covers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from slipstack.lib.material import Material, band_delta

__all__ = ["PATH_TOLERANCE", "SPREAD_TOLERANCE", "load_path", "pressure_spread", "OnsetKind", "OnsetBand"]

PATH_TOLERANCE = 0.15
"""Load paths closer than this are of one kind (a pure pull 0, a pure twist 1)."""
SPREAD_TOLERANCE = 0.1
"""Pressure spreads closer than this are of one kind (a flat face ≈ 0, a Hertzian tip ≈ 0.4)."""
_IN_CONTACT = 0.1
"""Taxels pressed with at least this share of the most pressed one are in the contact."""


def load_path(f_t: float, tau: float, mu_s: float, beta_s_m: float) -> float:
    """The torque's share of the load, ``(|τ|/β_s) / (|f_t|/μ_s + |τ|/β_s)`` in [0, 1]: 0 a
    pure force, 1 a pure torque (``f_t`` N, ``τ`` N·m about the pad origin); NaN without a
    load or without ``β_s`` (m)."""
    if not (beta_s_m > 0.0 and mu_s > 0.0):
        return math.nan
    force, torque = abs(f_t) / mu_s, abs(tau) / beta_s_m
    total = force + torque
    return torque / total if total > 0.0 and math.isfinite(total) else math.nan


def pressure_spread(phi: np.ndarray) -> float:
    """Coefficient of variation of the normal forces ``phi`` (N) over the taxels in contact
    (pressed with at least 10 % of the most pressed one): 0 for an evenly pressed face,
    about 0.4 for a Hertzian tip; NaN without a pressure frame."""
    if phi.size == 0:
        return math.nan
    top = float(phi.max())
    if not top > 0.0:
        return math.nan
    pressed = phi[phi >= _IN_CONTACT * top]
    return float(pressed.std() / pressed.mean())


@dataclass(frozen=True)
class OnsetKind:
    """Onsets of one kind: their mean load path and pressure spread (NaN: not measured),
    how many, and the band's width δ they give (dimensionless)."""

    path: float
    spread: float
    count: int
    delta: float

    def covers(self, path: float, spread: float) -> bool:
        """Whether a load of this path and spread is of this kind (an unmeasured spread
        matches only an unmeasured one)."""
        if math.isnan(spread) != math.isnan(self.spread):
            return False
        return abs(path - self.path) <= PATH_TOLERANCE and (
            math.isnan(spread) or abs(spread - self.spread) <= SPREAD_TOLERANCE)


@dataclass(frozen=True)
class OnsetBand:
    """The band's width δ (edge ``1 − δ``) for a load of a given path and pressure spread:
    ``lowest`` where no onset of its kind was identified, the onsets' ``kinds``, and the
    material's ``mu_s`` and ``beta_s_m`` (m) that normalise the load path."""

    lowest: float
    kinds: tuple[OnsetKind, ...]
    mu_s: float
    beta_s_m: float
    unidentified: float = math.nan
    """δ for a load path none of the identified onsets covers: the worst case (the sliding
    level, as without onsets), at least ``lowest`` — the onsets of other paths say nothing of it."""

    @classmethod
    def of(cls, material: Material) -> OnsetBand:
        """The band of ``material``'s identified onsets."""
        lowest = band_delta(material, material.onset_gamma)
        return cls(lowest, _kinds(material), material.mu_s, material.beta_s_m,
                   max(lowest, band_delta(material, ())))

    def delta_of_load(self, f_t: np.ndarray, tau: float, spread: float) -> float:
        """δ for the load ``f_t`` (2,) N, ``tau`` N·m about the pad origin, with a pressure of
        that ``spread``."""
        if not self.kinds:
            return self.lowest
        return self.delta(load_path(math.hypot(float(f_t[0]), float(f_t[1])), tau, self.mu_s, self.beta_s_m),
                          spread)

    def delta(self, path: float, spread: float) -> float:
        """The band's width δ for this load (:func:`load_path`, :func:`pressure_spread`)."""
        if math.isnan(path):
            return self.lowest
        kind = self.kind_of(path, spread)
        return self.unidentified if kind is None else kind.delta

    def kind_of(self, path: float, spread: float) -> OnsetKind | None:
        """The identified kind whose band a load of this path and spread gets: the one nearest
        in path among those that cover it; None where none does (or without a path)."""
        best = None
        for kind in self.kinds:
            if kind.covers(path, spread) and (best is None or abs(path - kind.path) < abs(path - best.path)):
                best = kind
        return best


def _kinds(material: Material) -> tuple[OnsetKind, ...]:
    """The identified onsets grouped by kind: each joins the first group whose first onset
    it matches (path within :data:`PATH_TOLERANCE`, spread within :data:`SPREAD_TOLERANCE`)."""
    n = len(material.onset_gamma)
    onsets = list(zip(material.onset_gamma, material.onset_path or (math.nan,) * n,
                      material.onset_spread or (math.nan,) * n))
    groups: list[list[tuple[float, float, float]]] = []
    for onset in onsets:
        if math.isnan(onset[1]):
            continue
        for group in groups:
            first = group[0]
            if OnsetKind(first[1], first[2], 1, math.nan).covers(onset[1], onset[2]):
                group.append(onset)
                break
        else:
            groups.append([onset])
    kinds = []
    for group in groups:
        levels = [g for g, _, _ in group]
        spreads = [k for _, _, k in group]
        kinds.append(OnsetKind(float(np.mean([p for _, p, _ in group])),
                               math.nan if math.isnan(spreads[0]) else float(np.mean(spreads)),
                               len(group), band_delta(material, levels)))
    return tuple(kinds)
