"""The contact in 3-D for Foxglove: a ``foxglove.SceneUpdate`` (JSON form) in the pad frame.

One entity, ``contact``, in frame ``pad`` (the pad frame F of docs/math.md §1, m): the
force of the latest pad-frame ``ft/wrench`` as an arrow from the pad origin (1 cm per N)
and the centre of rotation of the latest ``cor`` (when its case is ``rotation`` or
``on-taxel``) as a 2 mm sphere. :class:`ContactScene` keeps the latest of both and
writes the update; the live ``foxglove`` node and ``bag export`` both use it, so the
3-D panel of ``docs/foxglove_layout.json`` shows the same thing live and from a file.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from slipstack.lib.status import SlipCase
from slipstack.messages import Cor, Wrench
from slipstack.messages.json_schema import TIME_SCHEMA, wall_time

__all__ = ["ContactScene", "arrow_orientation", "SCENE_TOPIC", "SCENE_UPDATE_SCHEMA", "PAD_FRAME",
           "FORCE_ARROW_M_PER_N"]

SCENE_TOPIC = "/pad/scene"
PAD_FRAME = "pad"
"""Foxglove frame id of the pad frame F."""
FORCE_ARROW_M_PER_N = 0.01
_COR_CASES = (SlipCase.ROTATION, SlipCase.ON_TAXEL)

_NUMBER = {"type": "number"}
_VECTOR = {"type": "object", "properties": {k: _NUMBER for k in "xyz"}, "required": list("xyz"),
           "additionalProperties": False}
_COLOR = {"type": "object", "properties": {k: {"type": "number", "minimum": 0, "maximum": 1} for k in "rgba"},
          "required": list("rgba"), "additionalProperties": False}
_POSE = {"type": "object", "properties": {
    "position": _VECTOR,
    "orientation": {"type": "object", "properties": {k: _NUMBER for k in "xyzw"}, "required": list("xyzw"),
                    "additionalProperties": False}},
    "required": ["position", "orientation"], "additionalProperties": False}


def _primitive(**fields: Any) -> dict[str, Any]:
    props = {"pose": _POSE, **fields}
    return {"type": "array", "items": {"type": "object", "properties": props, "required": list(props),
                                       "additionalProperties": False}}


SCENE_UPDATE_SCHEMA: dict[str, Any] = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": "foxglove.SceneUpdate",
    "description": "An update to the entities of a 3-D scene (Foxglove's well-known schema; the parts used here)",
    "type": "object",
    "properties": {
        "deletions": {"type": "array", "maxItems": 0},
        "entities": {"type": "array", "items": {
            "type": "object",
            "properties": {
                "timestamp": TIME_SCHEMA,
                "frame_id": {"type": "string"},
                "id": {"type": "string"},
                "lifetime": {**TIME_SCHEMA, "title": "duration"},
                "frame_locked": {"type": "boolean"},
                "arrows": _primitive(shaft_length=_NUMBER, shaft_diameter=_NUMBER, head_length=_NUMBER,
                                     head_diameter=_NUMBER, color=_COLOR),
                "spheres": _primitive(size=_VECTOR, color=_COLOR),
            },
            "required": ["timestamp", "frame_id", "id", "lifetime", "frame_locked", "arrows", "spheres"],
            "additionalProperties": False,
        }},
    },
    "required": ["deletions", "entities"],
    "additionalProperties": False,
}
"""The JSON Schema of what :meth:`ContactScene.update` writes (named ``foxglove.SceneUpdate``)."""


def arrow_orientation(direction: np.ndarray) -> tuple[float, float, float, float]:
    """Quaternion ``(x, y, z, w)`` turning +x onto ``direction`` (a Foxglove arrow points along +x)."""
    n = float(np.linalg.norm(direction))
    if n == 0.0:
        return 0.0, 0.0, 0.0, 1.0
    ux, uy, uz = (float(c) / n for c in direction)
    if ux < -1.0 + 1e-9:  # opposite to +x: half a turn about z
        return 0.0, 0.0, 1.0, 0.0
    x, y, z, w = 0.0, -uz, uy, 1.0 + ux  # rotation axis x̂ × û, half angle from w
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    return x / norm, y / norm, z / norm, w / norm


def _pose(position: tuple[float, float, float], orientation: tuple[float, float, float, float]) -> dict[str, Any]:
    return {"position": dict(zip("xyz", position)), "orientation": dict(zip("xyzw", orientation))}


class ContactScene:
    """The latest pad-frame force and COR, and the scene update that shows them."""

    def __init__(self) -> None:
        self.force = np.zeros(3)
        self.cor: np.ndarray | None = None

    def on_wrench(self, msg: Wrench) -> bool:
        """Take the force of a pad-frame wrench; False (nothing to show) for a sensor-frame one."""
        if msg.frame != PAD_FRAME:
            return False
        self.force = np.asarray(msg.force, dtype=float)
        return True

    def on_cor(self, msg: Cor) -> bool:
        """Take the COR (none unless the case is rotation or on-taxel); always a change to show."""
        self.cor = np.asarray(msg.p_c, dtype=float) if msg.case in _COR_CASES else None
        return True

    def update(self, wall_ns: int) -> dict[str, Any]:
        """The ``foxglove.SceneUpdate`` (JSON form, :data:`SCENE_UPDATE_SCHEMA`) stamped ``wall_ns``."""
        length = float(np.linalg.norm(self.force)) * FORCE_ARROW_M_PER_N
        arrows = [{"pose": _pose((0.0, 0.0, 0.0), arrow_orientation(self.force)), "shaft_length": 0.8 * length,
                   "shaft_diameter": 0.001, "head_length": 0.2 * length, "head_diameter": 0.003,
                   "color": {"r": 1.0, "g": 0.3, "b": 0.1, "a": 1.0}}] if length else []
        spheres = [] if self.cor is None else [
            {"pose": _pose((float(self.cor[0]), float(self.cor[1]), 0.0), (0.0, 0.0, 0.0, 1.0)),
             "size": {"x": 0.002, "y": 0.002, "z": 0.002}, "color": {"r": 0.1, "g": 0.5, "b": 1.0, "a": 1.0}}]
        return {"deletions": [], "entities": [{
            "timestamp": wall_time(wall_ns), "frame_id": PAD_FRAME, "id": "contact",
            "lifetime": {"sec": 0, "nsec": 0}, "frame_locked": False, "arrows": arrows, "spheres": spheres}]}
