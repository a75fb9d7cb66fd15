"""The ``foxglove`` node: the running graph, live, in Foxglove (WebSocket protocol).

Serves ``ws://HOST:PORT`` with the Foxglove SDK (``pip install 'slipstack[foxglove]'``)
and, per received message (latest value per input; a viewer never slows the graph):

* every input topic as JSON with the JSON Schema of its message declaration
  (``/slipstack/<topic>``: slip state, γ, margin, grip force ... plottable by field);
* ``/pad/pressure``: the tactile frame as a ``foxglove.RawImage``, encoding ``32FC1``,
  one pixel per taxel, row 0 first, values in Pa (a heat map in the Image panel);
* ``/pad/scene``: a ``foxglove.SceneUpdate`` in frame ``pad`` (the pad frame F, m): the
  force of ``ft/wrench`` as an arrow from the pad origin (length 1 cm per N) and the
  centre of rotation from ``cor`` as a sphere.

Log times are wall-clock ns: each message's ``stamp_ns`` (CLOCK_MONOTONIC) plus the
host's wall − monotonic offset read at start. ``docs/foxglove_layout.json`` is a
layout with these panels.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from slipstack.lib.errors import ConfigError
from slipstack.messages import Cor, GripCommand, Message, Slip, TactileFrame, Wrench
from slipstack.nodes.recording.export import PAD_FRAME, PAD_IMAGE_TOPIC, foxglove_topic
from slipstack.nodes.runtime.node import Context, Input, Node

__all__ = ["FoxgloveBridge", "FoxgloveParams", "arrow_orientation"]

FORCE_ARROW_M_PER_N = 0.01
INSTALL_HINT = "the foxglove node needs the Foxglove SDK: pip install 'slipstack[foxglove]'"


@dataclass(frozen=True)
class FoxgloveParams:
    host: str = field(default="127.0.0.1", metadata={"help": "address the WebSocket server binds (0.0.0.0: all)"})
    port: int = field(default=8765, metadata={"help": "WebSocket port (Foxglove: Open connection, ws://HOST:PORT)"})


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


class FoxgloveBridge(Node):
    """Serves the graph's sensor, contact and control topics to Foxglove over WebSocket."""

    name = "foxglove"
    inputs = {
        "wrench": Input("ft/wrench", Wrench),
        "tactile": Input("tactile/frame", TactileFrame),
        "cor": Input("cor", Cor),
        "slip": Input("slip", Slip),
        "command": Input("grip/command", GripCommand),
    }
    Params = FoxgloveParams

    def __init__(self, params: FoxgloveParams | None = None) -> None:
        super().__init__(params)
        if not 0 < self.params.port < 65536:
            raise ConfigError(f"foxglove: port must be 1..65535, got {self.params.port}")
        self._server: Any = None
        self._json: dict[str, Any] = {}
        self._wall_offset_ns = 0
        self._force = np.zeros(3)
        self._cor: np.ndarray | None = None

    def start(self, ctx: Context) -> None:
        try:
            import foxglove
            from foxglove.channels import RawImageChannel, SceneUpdateChannel
        except ImportError:
            raise ConfigError(INSTALL_HINT) from None
        from slipstack.messages.json_schema import json_schema

        self._wall_offset_ns = time.time_ns() - time.monotonic_ns()
        self._server = foxglove.start_server(name="slipstack", host=self.params.host, port=self.params.port)
        for name, spec in self.inputs.items():
            self._json[name] = foxglove.Channel(foxglove_topic(spec.topic), schema=json_schema(spec.type))
        self._image = RawImageChannel(PAD_IMAGE_TOPIC)
        self._scene = SceneUpdateChannel("/pad/scene")
        ctx.log(f"serving Foxglove on ws://{self.params.host}:{self._server.port}")

    def stop(self, ctx: Context) -> None:
        if self._server is not None:
            self._server.stop()
            self._server = None

    # -- inputs --------------------------------------------------------------------------
    def on_wrench(self, msg: Wrench, ctx: Context) -> None:
        self._log_json("wrench", msg)
        if msg.frame == PAD_FRAME:
            self._force = np.asarray(msg.force, dtype=float)
            self._log_scene(msg)

    def on_tactile(self, msg: TactileFrame, ctx: Context) -> None:
        from foxglove.messages import RawImage

        self._log_json("tactile", msg)
        pixels = np.ascontiguousarray(msg.pressure_pa, dtype="<f4")
        self._image.log(RawImage(timestamp=self._timestamp(msg), frame_id=PAD_FRAME, width=msg.cols,
                                 height=msg.rows, encoding="32FC1", step=4 * msg.cols, data=pixels.tobytes()),
                        log_time=self._wall_ns(msg))

    def on_cor(self, msg: Cor, ctx: Context) -> None:
        self._log_json("cor", msg)
        self._cor = np.asarray(msg.p_c, dtype=float) if msg.case in ("rotation", "on-taxel") else None
        self._log_scene(msg)

    def on_slip(self, msg: Slip, ctx: Context) -> None:
        self._log_json("slip", msg)

    def on_command(self, msg: GripCommand, ctx: Context) -> None:
        self._log_json("command", msg)

    # -- output --------------------------------------------------------------------------
    def _wall_ns(self, msg: Message) -> int:
        return msg.header.stamp_ns + self._wall_offset_ns

    def _timestamp(self, msg: Message) -> Any:
        from foxglove.messages import Timestamp

        sec, nsec = divmod(self._wall_ns(msg), 1_000_000_000)
        return Timestamp(sec=sec, nsec=nsec)

    def _log_json(self, name: str, msg: Message) -> None:
        from slipstack.messages.json_schema import to_json

        self._json[name].log(to_json(msg, self._wall_offset_ns), log_time=self._wall_ns(msg))

    def _log_scene(self, msg: Message) -> None:
        from foxglove.messages import (
            ArrowPrimitive, Color, Pose, Quaternion, SceneEntity, SceneUpdate, SpherePrimitive, Vector3,
        )

        length = float(np.linalg.norm(self._force)) * FORCE_ARROW_M_PER_N
        qx, qy, qz, qw = arrow_orientation(self._force)
        arrows = [ArrowPrimitive(pose=Pose(position=Vector3(x=0.0, y=0.0, z=0.0),
                                           orientation=Quaternion(x=qx, y=qy, z=qz, w=qw)),
                                 shaft_length=0.8 * length, shaft_diameter=0.001, head_length=0.2 * length,
                                 head_diameter=0.003, color=Color(r=1.0, g=0.3, b=0.1, a=1.0))] if length else []
        spheres = [] if self._cor is None else [
            SpherePrimitive(pose=Pose(position=Vector3(x=float(self._cor[0]), y=float(self._cor[1]), z=0.0),
                                      orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)),
                            size=Vector3(x=0.002, y=0.002, z=0.002), color=Color(r=0.1, g=0.5, b=1.0, a=1.0))]
        entity = SceneEntity(timestamp=self._timestamp(msg), frame_id=PAD_FRAME, id="contact",
                             arrows=arrows, spheres=spheres)
        self._scene.log(SceneUpdate(entities=[entity]), log_time=self._wall_ns(msg))
