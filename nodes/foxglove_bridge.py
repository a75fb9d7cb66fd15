"""The ``foxglove`` node: the running graph, live, in Foxglove (WebSocket protocol).

Serves ``ws://HOST:PORT`` with the Foxglove SDK (``pip install 'slipstack[foxglove]'``;
subprotocol ``foxglove.sdk.v1``, or ``foxglove.websocket.v1``: :mod:`.foxglove_front`)
and, per received message (latest value per input; a viewer never slows the graph):

More in docs/modules.md, `nodes/foxglove_bridge.py`.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from slipstack.lib.errors import ConfigError
from slipstack.messages import Cor, GripCommand, Message, Slip, TactileFrame, Wrench
from slipstack.nodes.recording.export import PAD_IMAGE_TOPIC, foxglove_topic
from slipstack.nodes.recording.foxglove_scene import PAD_FRAME, SCENE_TOPIC, SCENE_UPDATE_SCHEMA, ContactScene
from slipstack.nodes.runtime.node import Context, Input, Node

__all__ = ["FoxgloveBridge", "FoxgloveParams"]

INSTALL_HINT = "the foxglove node needs the Foxglove SDK: pip install 'slipstack[foxglove]'"


@dataclass(frozen=True)
class FoxgloveParams:
    host: str = field(default="127.0.0.1", metadata={"help": "address the WebSocket server binds (0.0.0.0: all)"})
    port: int = field(default=8765, metadata={"help": "WebSocket port (Foxglove: Open connection, ws://HOST:PORT)"})


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
        self._front: Any = None
        self._json: dict[str, Any] = {}
        self._wall_offset_ns = 0
        self._contact = ContactScene()

    def start(self, ctx: Context) -> None:
        try:
            import foxglove
            from foxglove.channels import RawImageChannel
        except ImportError:
            raise ConfigError(INSTALL_HINT) from None
        from slipstack.messages.json_schema import json_schema

        self._wall_offset_ns = time.time_ns() - time.monotonic_ns()
        from slipstack.nodes.foxglove_front import SubprotocolFront

        self._server = foxglove.start_server(name="slipstack", host="127.0.0.1", port=0)  # behind the front
        try:
            self._front = SubprotocolFront(self.params.host, self.params.port, self._server.port)
        except OSError as exc:
            self._server.stop()
            raise ConfigError(f"foxglove: cannot listen on {self.params.host}:{self.params.port} ({exc.strerror}); "
                              "choose another foxglove_port:=") from None
        for name, spec in self.inputs.items():
            self._json[name] = foxglove.Channel(foxglove_topic(spec.topic), schema=json_schema(spec.type))
        self._image = RawImageChannel(PAD_IMAGE_TOPIC)
        scene_schema = foxglove.Schema(name=SCENE_UPDATE_SCHEMA["title"], encoding="jsonschema",
                                       data=json.dumps(SCENE_UPDATE_SCHEMA).encode())
        self._scene = foxglove.Channel(SCENE_TOPIC, schema=scene_schema, message_encoding="json")
        ctx.log(f"serving Foxglove on ws://{self.params.host}:{self._front.port} (subprotocol foxglove.sdk.v1, "
                "or foxglove.websocket.v1 for older clients)")

    def stop(self, ctx: Context) -> None:
        if self._front is not None:
            self._front.close()
            self._front = None
        if self._server is not None:
            self._server.stop()
            self._server = None

    # -- inputs --------------------------------------------------------------------------
    def on_wrench(self, msg: Wrench, ctx: Context) -> None:
        self._log_json("wrench", msg)
        if self._contact.on_wrench(msg):
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
        if self._contact.on_cor(msg):
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
        self._scene.log(self._contact.update(self._wall_ns(msg)), log_time=self._wall_ns(msg))
