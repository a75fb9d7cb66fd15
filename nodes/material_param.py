"""The ``material`` parameter of the nodes that need friction: fills what was not given.

A node's parameter dataclass names a material file (``material``: a shipped name in
``launch/materials/``, e.g. ``rubber``, or a path; ``""``: none given, the shipped
:data:`DEFAULT_MATERIAL`, which the slip detector reports as uncalibrated) and leaves the friction-derived
parameters at NaN ("from the material"). :func:`fill_from_material` replaces each NaN
one by the material's value (``lib/material.py`` states the rule for ``delta`` and
``gamma_release``); a value given explicitly is kept. Loaded files are cached (at most
``_CACHE_SIZE``), keyed by their resolved path.
"""

from __future__ import annotations

import functools
import math
from pathlib import Path
from typing import Any

from slipstack.lib.errors import ConfigError
from slipstack.lib.material import QUANTITY, Material, detector_thresholds, implausible, load_material
from slipstack.lib.toml_file import resolve_path

__all__ = ["DEFAULT_MATERIAL", "resolve_material", "fill_from_material", "refuse_implausible"]

DEFAULT_MATERIAL = "rubber"
"""What a run without a material file uses (``launch/materials/rubber.toml``, the simulated
rig's rubber; its provenance is in the file)."""

_CACHE_SIZE = 16


@functools.lru_cache(maxsize=_CACHE_SIZE)
def _load(path: Path) -> Material:
    return load_material(path)


def resolve_material(name: str) -> Material:
    """The material ``name`` (a path, or a shipped name with or without ``.toml``; ``""``:
    :data:`DEFAULT_MATERIAL`).

    Raises:
        ConfigError: no such file, or an invalid one (naming the key).
    """
    return _load(resolve_path(name or DEFAULT_MATERIAL, Path.cwd(), "materials"))


def _value(material: Material, source: str) -> float:
    if source in ("delta", "gamma_release", "gamma_resume"):
        return getattr(detector_thresholds(material), source)
    return float(getattr(material, source))


def refuse_implausible(params: Any, **sources: str) -> None:
    """Refuse each given (not NaN) field ``name`` of ``params`` whose value lies outside the
    plausible range of the material quantity ``sources[name]`` (``mu_s``, ``beta_s_m``, ``delta``…).

    Raises:
        ConfigError: naming the field, the range and what to do.
    """
    for name, src in sources.items():
        if why := implausible(src, getattr(params, name)):
            raise ConfigError(f"{name} := {getattr(params, name):g} lies {why}: a typo? Correct it, or leave "
                              f"{name} at nan to take the material's")


def fill_from_material(params: Any, **sources: str) -> None:
    """Set each NaN field ``name`` of the frozen dataclass ``params`` from its material.

    ``sources`` maps a field to the material quantity it takes: a :class:`Material`
    attribute (``mu_s``, ``beta_s_m``, …) or ``delta`` / ``gamma_release`` / ``gamma_resume`` (derived).
    The material is read only if some field is NaN. A friction value given implausible is
    refused (:func:`refuse_implausible`).
    """
    refuse_implausible(params, **{name: src for name, src in sources.items() if src in QUANTITY})
    missing = {name: src for name, src in sources.items() if math.isnan(getattr(params, name))}
    if not missing:
        return
    material = resolve_material(params.material)
    for name, src in missing.items():
        object.__setattr__(params, name, _value(material, src))
