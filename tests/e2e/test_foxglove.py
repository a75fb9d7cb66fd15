"""The live ``foxglove`` node against a real WebSocket client.

The test process publishes a wrench and a 16x16 tactile frame on its own XPUB; the node
runs as ``slipstack run foxglove`` subscribed to it; a ``websockets`` client speaks the
Foxglove WebSocket protocol (subprotocol ``foxglove.sdk.v1``, or its older name
``foxglove.websocket.v1``): reads the advertised channels, subscribes, and decodes what arrives.
"""

from __future__ import annotations

import json
import struct
import subprocess
import sys
import time

import numpy as np
import pytest
import zmq
from free_ports import free_port

pytest.importorskip("foxglove", reason="the foxglove extra is not installed")
sync_client = pytest.importorskip("websockets.sync.client", reason="websockets (a WebSocket client) is not installed")

from slipstack.messages import Header, TactileFrame, Wrench, encode  # noqa: E402
from slipstack.nodes.runtime.transport import make_pub  # noqa: E402

pytestmark = pytest.mark.e2e

SUBPROTOCOLS = ("foxglove.sdk.v1", "foxglove.websocket.v1")  # the SDK's name, and older clients'
MESSAGE_DATA = 0x01


def _frames(k: int) -> list[tuple[str, bytes]]:
    stamp = time.monotonic_ns()
    pressure = np.arange(256, dtype="<f4") * 10.0 + k
    return [
        ("ft/wrench", encode(Wrench(force=np.array([0.0, 3.0, -4.0]), torque=np.zeros(3), frame="pad",
                                    header=Header(stamp, k, stamp, {})))),
        ("tactile/frame", encode(TactileFrame(pressure_pa=pressure, saturated=np.zeros(256, bool),
                                              dead=np.zeros(256, bool), header=Header(stamp, k, stamp, {})))),
    ]


def _start_node(tmp_path, endpoint: str) -> tuple[subprocess.Popen, int, object]:
    """``slipstack run foxglove`` on a free port, subscribed to ``endpoint``; (process, port, log file)."""
    port = free_port()
    log = open(tmp_path / "foxglove.log", "wb")
    proc = subprocess.Popen(
        [sys.executable, "-m", "slipstack.launch.cli", "run", "foxglove", f"port:={port}",
         "--sub", f"ft/wrench={endpoint}", "--sub", f"tactile/frame={endpoint}"],
        stdout=log, stderr=subprocess.STDOUT)
    return proc, port, log


def _connect(proc: subprocess.Popen, port: int, subprotocol: str, tmp_path):
    deadline = time.monotonic() + 30
    while True:
        assert proc.poll() is None and time.monotonic() < deadline, (tmp_path / "foxglove.log").read_text()
        try:
            return sync_client.connect(f"ws://127.0.0.1:{port}", subprotocols=[subprotocol], open_timeout=2)
        except OSError:
            time.sleep(0.2)


@pytest.mark.parametrize("subprotocol", SUBPROTOCOLS)
def test_a_websocket_client_subscribes_and_decodes_the_live_graph(tmp_path, subprotocol):
    """Under either name of the protocol (a ``foxglove.websocket.v1`` client got "400 Missing
    expected sec-websocket-protocol header" from the SDK)."""
    endpoint = f"ipc://{tmp_path}/bus.pub"
    pub = make_pub(zmq.Context.instance(), endpoint)
    proc, port, log = _start_node(tmp_path, endpoint)
    try:
        ws = _connect(proc, port, subprotocol, tmp_path)
        deadline = time.monotonic() + 30
        with ws:
            assert ws.subprotocol == subprotocol
            channels: dict[str, dict] = {}
            while not {"/slipstack/ft/wrench", "/pad/pressure", "/pad/scene"} <= set(channels):
                msg = json.loads(ws.recv(timeout=10))
                if msg.get("op") == "advertise":
                    channels.update({c["topic"]: c for c in msg["channels"]})
            assert channels["/pad/pressure"]["schemaName"] == "foxglove.RawImage"
            assert channels["/pad/scene"]["schemaName"] == "foxglove.SceneUpdate"
            wrench_schema = json.loads(channels["/slipstack/ft/wrench"]["schema"])
            assert "force" in wrench_schema["properties"]
            wanted = {"/slipstack/ft/wrench": 1, "/pad/pressure": 2}
            ws.send(json.dumps({"op": "subscribe", "subscriptions": [
                {"id": sub_id, "channelId": channels[topic]["id"]} for topic, sub_id in wanted.items()]}))
            got: dict[int, bytes] = {}
            k = 0
            while len(got) < len(wanted):
                assert time.monotonic() < deadline + 30, f"received only {sorted(got)}"
                for topic, payload in _frames(k):  # until the node has joined and forwarded both
                    pub.send_multipart((topic.encode(), payload))
                k += 1
                try:
                    frame = ws.recv(timeout=0.2)
                except TimeoutError:
                    continue
                if isinstance(frame, bytes) and frame[0] == MESSAGE_DATA:
                    sub_id, _log_time = struct.unpack_from("<IQ", frame, 1)
                    got[sub_id] = frame[13:]
            wrench = json.loads(got[1])
            assert wrench["force"] == [0.0, 3.0, -4.0] and wrench["frame"] == "pad"
            # the pad as an image: the 16x16 float32 pressures, row 0 first, inside the RawImage
            image = got[2]
            assert any((np.arange(256, dtype="<f4") * 10.0 + j).tobytes() in image for j in range(k))
    finally:
        proc.terminate()
        proc.wait(20)
        log.close()
        pub.close(linger=0)


def test_a_client_of_another_protocol_is_told_what_the_node_speaks(tmp_path):
    import http.client

    proc, port, log = _start_node(tmp_path, f"ipc://{tmp_path}/bus.pub")
    try:
        with _connect(proc, port, SUBPROTOCOLS[0], tmp_path):  # it is up
            pass
        conn = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
        conn.request("GET", "/", headers={"Upgrade": "websocket", "Connection": "Upgrade", "Sec-WebSocket-Version": "13",
                                          "Sec-WebSocket-Key": "dGhlIHNhbXBsZSBub25jZQ==",
                                          "Sec-WebSocket-Protocol": "chat"})
        answer = conn.getresponse()
        assert answer.status == 400
        assert b"subprotocol foxglove.sdk.v1 (foxglove.websocket.v1 is accepted too)" in answer.read()
    finally:
        proc.terminate()
        proc.wait(20)
        log.close()
