"""Material files: the identified friction of one contact, and the thresholds derived from it.

A material file (TOML, written by ``slipstack identify``; shipped ones in
``launch/materials/``) holds what the paper's Fig. 4 identification measures::

More in docs/modules.md, `lib/material.py`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from slipstack.lib.errors import ConfigError
from slipstack.lib.toml_file import read_toml

__all__ = ["Material", "DetectorThresholds", "band_delta", "detector_thresholds", "load_material", "material_toml",
           "implausible", "NOISE_FLOOR", "DELTA_MIN", "DELTA_MAX", "PLAUSIBLE", "QUANTITY"]

NOISE_FLOOR = 0.002
DELTA_MIN = 0.005
DELTA_MAX = 0.5
PLAUSIBLE = {"mu": (0.02, 3.0), "beta_m": (0.0, 0.1), "delta": (0.0, DELTA_MAX)}
"""The plausible range (inclusive) of a friction coefficient μ (μ_s, μ_d; dimensionless), a
torsional coefficient β (m) and a band δ (dimensionless); outside it a value is a typo
(docs/materials.md)."""
QUANTITY = {"mu_s": "mu", "mu_d": "mu", "beta_s_m": "beta_m", "beta_d_m": "beta_m", "delta": "delta"}
"""The material fields with a plausible range, and the quantity (a key of PLAUSIBLE) each is."""
_BAND_SIGMAS = 3.0
_RELEASE_SIGMAS = 4.0
_RESUME_SIGMAS = 2.0


@dataclass(frozen=True)
class Material:
    """Identified friction of one contact (see the module docstring for the file).

    Coefficients are dimensionless, β in m, ``*_se`` are standard errors in the same
    unit (NaN: not identified), ``*_model`` their model errors (same unit; NaN: not
    estimated). ``onset_gamma``: the load factor at the start of each identified
    gross-slip episode, in the order found; ``onset_path``, ``onset_spread``: the load path
    and pressure spread there (``lib/onset_band.py``; empty, or one per onset, NaN where
    not measured).
    """

    name: str
    mu_s: float
    mu_d: float
    provenance: str = ""
    mu_s_se: float = math.nan
    mu_d_se: float = math.nan
    beta_s_m: float = math.nan
    beta_s_se_m: float = math.nan
    beta_d_m: float = math.nan
    beta_d_se_m: float = math.nan
    mu_s_model: float = math.nan
    mu_d_model: float = math.nan
    beta_s_model_m: float = math.nan
    beta_d_model_m: float = math.nan
    gamma_noise_stick: float = math.nan
    gamma_noise_slide: float = math.nan
    force_noise_n: float = math.nan
    torque_noise_nm: float = math.nan
    onset_gamma: tuple[float, ...] = field(default_factory=tuple)
    onset_path: tuple[float, ...] = field(default_factory=tuple)
    onset_spread: tuple[float, ...] = field(default_factory=tuple)
    refused: str = ""

    def __post_init__(self) -> None:
        if not (math.isfinite(self.mu_s) and self.mu_s > 0):
            raise ConfigError(f"material {self.name!r}: mu_s must be a finite number > 0, got {self.mu_s}")
        if not (math.isfinite(self.mu_d) and 0 < self.mu_d <= self.mu_s * (1 + 1e-9)):
            raise ConfigError(f"material {self.name!r}: mu_d must lie in (0, mu_s = {self.mu_s}], got {self.mu_d}")
        for g in self.onset_gamma:
            if not (math.isfinite(g) and 0 < g <= 1.5):
                raise ConfigError(f"material {self.name!r}: onset_gamma entries must lie in (0, 1.5], got {g}")
        for key in ("onset_path", "onset_spread"):
            values = getattr(self, key)
            if values and len(values) != len(self.onset_gamma):
                raise ConfigError(f"material {self.name!r}: {key} needs one entry per onset_gamma "
                                  f"({len(self.onset_gamma)}), got {len(values)}")
            if any(not (math.isnan(v) or 0.0 <= v <= (1.0 if key == "onset_path" else 10.0)) for v in values):
                raise ConfigError(f"material {self.name!r}: {key} entries must lie in "
                                  f"[0, {1 if key == 'onset_path' else 10}] or be nan, got {list(values)}")

    @property
    def sliding_level(self) -> float:
        """The lowest load factor a sliding contact keeps: ``μ_d/μ_s``, or ``β_d/β_s`` if
        identified and lower (dimensionless)."""
        torsion = self.beta_d_m / self.beta_s_m if self.beta_s_m > 0 else math.nan
        return min(1.0, self.mu_d / self.mu_s, torsion if math.isfinite(torsion) else 1.0)


@dataclass(frozen=True)
class DetectorThresholds:
    """The detector's onset band ``delta``, latch ``gamma_release``, the level
    ``gamma_resume`` at which a frame restarts the release dwell, and the contact's
    ``sliding_level`` with the ``stuck_margin`` above it that proves it sticks after a
    slip (dimensionless; NaN: no such release)."""

    delta: float
    gamma_release: float
    gamma_resume: float
    sliding_level: float = math.nan
    stuck_margin: float = math.nan


def implausible(key: str, value: float) -> str:
    """Why ``value`` of ``key`` (``mu_s``, ``mu_d``, ``beta_s_m``, ``beta_d_m`` or ``delta``)
    is no plausible one, as ``outside …``; "" if it is, or is NaN (not given)."""
    quantity = QUANTITY[key]
    low, high = PLAUSIBLE[quantity]
    if math.isnan(value) or low <= value <= high:
        return ""
    return f"outside the plausible {quantity} [{low:g}, {high:g}] (docs/materials.md)"


def _noise(value: float) -> float:
    return max(value, NOISE_FLOOR) if math.isfinite(value) else NOISE_FLOOR


def band_delta(material: Material, onsets: tuple[float, ...] | list[float]) -> float:
    """The band's width δ (its edge ``1 − δ``) from ``onsets`` (load factors at gross-slip
    onsets of ``material``; none: its sliding level), by the rule of the module docstring."""
    stick = _noise(material.gamma_noise_stick)
    edge = material.sliding_level - _BAND_SIGMAS * stick  # the worst case, without onsets
    if onsets:
        below_lowest = (max(onsets) - min(onsets)) / (len(onsets) + 1)
        edge = min(min(onsets), 1.0) - below_lowest - _BAND_SIGMAS * stick
    return min(max(1.0 - edge, DELTA_MIN), DELTA_MAX)


def detector_thresholds(material: Material) -> DetectorThresholds:
    """Band and release level from a material, by the rule of the module docstring."""
    delta = band_delta(material, material.onset_gamma)
    release = material.sliding_level - _RELEASE_SIGMAS * _noise(material.gamma_noise_slide)
    release = min(max(release, 1e-3), 1.0 - delta)
    resume = material.sliding_level - _RESUME_SIGMAS * _noise(material.gamma_noise_slide)
    resume = max(release, min(resume, 1.0 - delta))
    return DetectorThresholds(delta=delta, gamma_release=release, gamma_resume=resume,
                              sliding_level=material.sliding_level,
                              stuck_margin=_RELEASE_SIGMAS * _noise(material.gamma_noise_slide))


_FLOATS = ("mu_s", "mu_d", "mu_s_se", "mu_d_se", "beta_s_m", "beta_s_se_m", "beta_d_m", "beta_d_se_m",
           "mu_s_model", "mu_d_model", "beta_s_model_m", "beta_d_model_m", "gamma_noise_stick", "gamma_noise_slide",
           "force_noise_n", "torque_noise_nm")
_LISTS = ("onset_gamma", "onset_path", "onset_spread")


def _number(table: dict[str, Any], key: str, source: str) -> float:
    value = table.pop(key, math.nan)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f"{source}: material.{key}: must be a number, got {value!r}")
    return float(value)


def parse_material(data: dict[str, Any], *, source: str = "<material>") -> Material:
    """A :class:`Material` from a parsed TOML mapping (``source`` names it in errors)."""
    table = data.get("material")
    if not isinstance(table, dict) or set(data) - {"material"}:
        raise ConfigError(f"{source}: a material file has exactly one table, [material] "
                          "(write one with `slipstack identify RECORDING... -o FILE`)")
    table = dict(table)
    for key in ("mu_s", "mu_d"):
        if key not in table:
            raise ConfigError(f"{source}: material.{key}: missing required key")
    name = table.pop("name", Path(source).stem)
    provenance = table.pop("provenance", "")
    refused = table.pop("refused", "")
    lists = {key: table.pop(key, []) for key in _LISTS}
    if not isinstance(name, str) or not isinstance(provenance, str) or not isinstance(refused, str):
        raise ConfigError(f"{source}: material.name, material.provenance and material.refused must be strings")
    for key, values in lists.items():
        if not isinstance(values, list) or any(isinstance(g, bool) or not isinstance(g, (int, float)) for g in values):
            raise ConfigError(f"{source}: material.{key}: must be a list of numbers, got {values!r}")
    values = {key: _number(table, key, source) for key in _FLOATS}
    if table:
        raise ConfigError(f"{source}: material.{sorted(table)[0]}: unknown key (known: name, provenance, "
                          f"refused, {', '.join(_LISTS)}, {', '.join(_FLOATS)})")
    try:
        material = Material(name=name, provenance=provenance, refused=refused,
                            **{key: tuple(float(g) for g in v) for key, v in lists.items()}, **values)
    except ConfigError as exc:
        raise ConfigError(f"{source}: {exc}") from None
    for key in () if refused else QUANTITY.keys() & values.keys():  # identify --force writes an
        if why := implausible(key, values[key]):  # implausible one marked refused; the detector says so
            raise ConfigError(f"{source}: material.{key} = {values[key]:g} lies {why}: a typo? Correct it, or "
                              "identify the contact: slipstack identify RAMP.mcap... -o FILE")
    return material


def load_material(path: str | Path) -> Material:
    """Read and validate a material file.

    Raises:
        ConfigError: unreadable file, TOML syntax error, or an invalid key (named).
    """
    return parse_material(read_toml(path, "material"), source=Path(path).name)


def _toml_value(value: Any) -> str:
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, tuple):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    return "nan" if not math.isfinite(value) else f"{float(value):.6g}"


def material_toml(material: Material, comment: str = "") -> str:
    """The material as the text of a material file (``comment`` lines go on top)."""
    lines = [f"# {line}" if line else "#" for line in comment.splitlines()]
    t = detector_thresholds(material)
    lines.append(f"# derived detector thresholds (lib/material.py): delta = {t.delta:.4f}, "
                 f"gamma_release = {t.gamma_release:.4f}, gamma_resume = {t.gamma_resume:.4f}")
    lines.append("[material]")
    lists = tuple(key for key in _LISTS if key == "onset_gamma" or getattr(material, key))
    for key in ("name", "provenance", *(("refused",) if material.refused else ()), *_FLOATS, *lists):
        lines.append(f"{key} = {_toml_value(getattr(material, key))}")
    return "\n".join(lines) + "\n"
