"""Tactile calibration: raw counts → pressure (Pa), with dead and saturated taxels.

The model, per taxel i with raw count c_i::

    p_i = table(g_i · c_i)        (Pa)

More in docs/modules.md, `lib/calibration.py`.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import ConfigError
from .toml_file import loads as toml_loads

__all__ = ["Calibration", "CalibratedFrame", "load_calibration", "save_calibration"]


@dataclass(frozen=True)
class CalibratedFrame:
    """Result of :meth:`Calibration.apply`; arrays have the shape of the input counts."""

    pressure_pa: np.ndarray
    saturated: np.ndarray
    dead: np.ndarray


@dataclass(frozen=True)
class Calibration:
    """A calibration table (module docstring). Invalid tables raise ConfigError."""

    counts: np.ndarray
    pressure_pa: np.ndarray
    gain: np.ndarray | None = None
    dead: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    saturation_counts: int | None = None

    def __post_init__(self) -> None:
        c = np.asarray(self.counts, dtype=float)
        p = np.asarray(self.pressure_pa, dtype=float)
        if c.ndim != 1 or c.shape != p.shape or len(c) < 2:
            raise ConfigError("calibration: counts and pressure_pa must be 1-D lists of equal length >= 2")
        if not np.all(np.isfinite(c)) or not np.all(np.isfinite(p)):
            raise ConfigError("calibration: counts and pressure_pa must be finite")
        if np.any(np.diff(c) <= 0):
            raise ConfigError("calibration: counts must be strictly increasing")
        if np.any(np.diff(p) < 0) or p[0] < 0:
            raise ConfigError("calibration: pressure_pa must be non-negative and non-decreasing (monotone)")
        object.__setattr__(self, "counts", c)
        object.__setattr__(self, "pressure_pa", p)
        if self.gain is not None:
            g = np.asarray(self.gain, dtype=float).ravel()
            if not np.all(np.isfinite(g)) or np.any(g <= 0):
                raise ConfigError("calibration: gain must be finite and > 0 for every taxel")
            object.__setattr__(self, "gain", g)
        d = np.asarray(self.dead, dtype=np.int64).ravel()
        if np.any(d < 0):
            raise ConfigError("calibration: dead taxel indices must be >= 0")
        object.__setattr__(self, "dead", np.unique(d))
        if self.saturation_counts is not None and self.saturation_counts <= 0:
            raise ConfigError("calibration: saturation_counts must be > 0")

    def check_size(self, n_taxels: int) -> None:
        """Raise ConfigError unless the per-taxel data fit a pad of *n_taxels*."""
        if self.gain is not None and len(self.gain) != n_taxels:
            raise ConfigError(f"calibration: gain has {len(self.gain)} entries, the pad has {n_taxels} taxels")
        if len(self.dead) and self.dead[-1] >= n_taxels:
            raise ConfigError(f"calibration: dead index {self.dead[-1]} is >= the pad's {n_taxels} taxels")

    def apply(self, counts: np.ndarray) -> CalibratedFrame:
        """Pressure (Pa), saturation and dead masks for raw *counts* (any shape, row-major).

        The sizes must have been checked with :meth:`check_size` (done at load time
        by the caller); this method does not raise on counts.
        """
        raw = np.asarray(counts)
        flat = raw.ravel().astype(float)
        if self.gain is not None:
            flat = flat * self.gain
        p = np.interp(flat, self.counts, self.pressure_pa)
        dead = np.zeros(flat.shape, dtype=bool)
        if len(self.dead):  # none is the common case: no indexing at every frame then
            dead[self.dead] = True
            p[self.dead] = 0.0
        if self.saturation_counts is None:
            sat = np.zeros(flat.shape, dtype=bool)
        else:
            sat = raw.ravel() >= self.saturation_counts
        if raw.ndim == 1:  # the driver's flat frame: the arrays have its shape already
            return CalibratedFrame(p, sat, dead)
        return CalibratedFrame(p.reshape(raw.shape), sat.reshape(raw.shape), dead.reshape(raw.shape))

    def to_toml(self) -> str:
        """TOML text in the module's file format (round-trips through :func:`from_toml`)."""
        def arr(values: np.ndarray, fmt: str) -> str:
            return "[" + ", ".join(format(v, fmt) for v in values) + "]"

        lines = [f"counts = {arr(self.counts, '.17g')}", f"pressure_pa = {arr(self.pressure_pa, '.17g')}"]
        if self.gain is not None:
            lines.append(f"gain = {arr(self.gain, '.17g')}")
        if len(self.dead):
            lines.append(f"dead = {arr(self.dead, 'd')}")
        if self.saturation_counts is not None:
            lines.append(f"saturation_counts = {int(self.saturation_counts)}")
        return "\n".join(lines) + "\n"

    @classmethod
    def from_toml(cls, text: str) -> Calibration:
        """Parse TOML text; ConfigError names the problem."""
        try:
            d = toml_loads(text)
        except tomllib.TOMLDecodeError as e:
            raise ConfigError(f"calibration: not valid TOML: {e}") from e
        unknown = set(d) - {"counts", "pressure_pa", "gain", "dead", "saturation_counts"}
        if unknown:
            raise ConfigError(f"calibration: unknown keys {sorted(unknown)}")
        for key in ("counts", "pressure_pa"):
            if key not in d:
                raise ConfigError(f"calibration: missing key {key!r}")
        try:
            return cls(
                counts=np.array(d["counts"], dtype=float),
                pressure_pa=np.array(d["pressure_pa"], dtype=float),
                gain=None if "gain" not in d else np.array(d["gain"], dtype=float),
                dead=np.array(d.get("dead", []), dtype=np.int64),
                saturation_counts=d.get("saturation_counts"),
            )
        except (TypeError, ValueError) as e:
            raise ConfigError(f"calibration: bad value: {e}") from e


def load_calibration(path: str | Path) -> Calibration:
    """Read a calibration TOML file (module docstring)."""
    return Calibration.from_toml(Path(path).read_text(encoding="utf-8"))


def save_calibration(calibration: Calibration, path: str | Path) -> None:
    """Write *calibration* as TOML to *path*."""
    Path(path).write_text(calibration.to_toml(), encoding="utf-8")
