"""Every node with bus inputs, fuzzed through decode and its handler on the
in-process executor: valid frames (any values the declarations allow) and hostile
ones (random bytes, corrupted payloads, the wrong type, resource bombs).

More in docs/modules.md, `tests/property/test_node_fuzz_budget.py`.
"""

from __future__ import annotations

import gc
import socket
import time
import tracemalloc
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import pytest
from free_ports import free_port
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from msg_strategies import valid_message

from slipstack.lib.errors import DecodeError
from slipstack.messages import (
    Contact, Cor, Diagnostics, GraspGoal, GripCommand, GripState, Header, Message, RigTruth, Slip, TactileFrame,
    Wrench, decode, encode,
)
from slipstack.messages.codec import packb
from slipstack.nodes.catalog import node_class
from slipstack.nodes.runtime.inprocess import InProcessExecutor
from slipstack.nodes.runtime.node import make_params

CPU_FACTOR = 50
MEMORY_FACTOR = 50
CPU_FLOOR_S = 0.002
MEMORY_FLOOR_BYTES = 256 << 10

MS = 1_000_000


def _pad(rows: int = 16, cols: int = 16) -> np.ndarray:
    """A Hertzian-like pressure blob, Pa, row-major."""
    y, x = np.mgrid[0:rows, 0:cols]
    r2 = ((x - cols / 2) ** 2 + (y - rows / 2) ** 2) / (rows / 4) ** 2
    return (4e4 * np.clip(1 - r2, 0, None)).astype(np.float32).ravel()


def _nominal_frames() -> dict[type[Message], Message]:
    """One typical message per type: a 16×16 pad, a loaded contact in the pad frame."""
    from slipstack.nodes.fusion import Fusion

    wrench = Wrench(force=np.array([0.8, 0.3, -6.0]), torque=np.array([0.0, 0.0, 0.004]), frame="pad")
    tactile = TactileFrame(pressure_pa=_pad(), saturated=np.zeros(256, bool), dead=np.zeros(256, bool))
    fusion = InProcessExecutor([Fusion()])
    fusion.feed([(1 * MS, "tactile/frame", encode(tactile, Header(1 * MS, 0, 1 * MS, {}))),
                 (2 * MS, "ft/wrench", encode(wrench, Header(2 * MS, 0, 2 * MS, {})))])
    fusion.run()
    contact = fusion.published["contact"][-1]
    assert contact.has_tactile and contact.status == "ok"
    return {
        Wrench: wrench, TactileFrame: tactile, Contact: contact,
        Cor: Cor(case="rotation", p_c=np.array([1e-3, 0.0]), torque_capacity=0.01, load_torque=0.004, gamma=0.4,
                 converged=True),
        Slip: Slip(state="stick", margin=0.6, method="exact", verdicts={"exact": [True, 0.6]}, gamma=0.4,
                   f_n=contact.f_n, f_t=contact.f_t, tau=contact.tau),
        GripCommand: GripCommand(f_n_desired=6.0, law="exact", reason="nominal"),
        GripState: GripState(f_n_command=6.0, mode="following"),
        RigTruth: RigTruth(f_n_applied=6.0, f_n_command=6.0),
        Diagnostics: Diagnostics(node="fusion", counters={"in.contact.received": 10}),
        GraspGoal: GraspGoal(mode="pivot", angle_rad=0.52, rate_rad_s=0.52),
    }


@dataclass
class _Case:
    type_name: str
    params: Callable[[Path], dict] = lambda tmp: {}


CASES = {
    "fusion": _Case("fusion"),
    "cor_estimator": _Case("cor_estimator"),
    "slip_detector": _Case("slip_detector"),
    "grip_controller": _Case("grip_controller"),
    "grip_controller-tactile14": _Case("grip_controller", lambda tmp: {"law": "tactile14"}),
    "monitor": _Case("monitor"),
    "grasp": _Case("grasp"),
    "grasp_planner": _Case("grasp_planner"),
    "relay": _Case("relay"),
    "sink": _Case("sink"),
    # the rig refuses rdt_port 0 (a driver could not find its emulator): a port free now
    "rig": _Case("rig", lambda tmp: {"rdt_port": free_port(socket.SOCK_DGRAM), "tactile_link": str(tmp / "tactile.tty")}),
}


class _Harness:
    """One node on an in-process executor; frames fed one at a time, each measured."""

    def __init__(self, case: _Case, tmp: Path) -> None:
        cls = node_class(case.type_name)
        self.node = cls(make_params(cls.Params, case.params(tmp), case.type_name))
        self.ex = InProcessExecutor([self.node])
        self.host = self.ex.hosts[0]
        self.t = 10 * MS
        self.seq = 0

    def feed(self, input_name: str, payload: bytes) -> tuple[float, int]:
        """Handle one frame; returns (process CPU seconds, allocation peak in bytes)."""
        self.t += MS
        self.ex.feed([(self.t, self.host.input_topics[input_name], payload)])
        gc.disable()
        tracemalloc.start()
        t0 = time.process_time()
        try:
            self.ex.run()
            cpu = time.process_time() - t0
            _, peak = tracemalloc.get_traced_memory()
        finally:
            tracemalloc.stop()
            gc.enable()
        return cpu, peak

    def stamped(self, msg: Message) -> bytes:
        self.seq += 1
        return encode(msg, Header(self.t + MS, self.seq, self.t + MS, {}))


_NOMINAL: dict[str, tuple[float, int]] = {}


def _budget(name: str, harness: _Harness, nominal: dict[type[Message], Message]) -> tuple[float, int]:
    """(CPU s, bytes) allowed per frame: the factors × the node's dearest nominal frame."""
    if name not in _NOMINAL:
        costs = []
        for input_name, spec in harness.node.inputs.items():
            msg = nominal[spec.type]
            for _ in range(5):  # warm: kernels loaded, caches filled
                harness.feed(input_name, harness.stamped(msg))
            runs = [harness.feed(input_name, harness.stamped(msg)) for _ in range(15)]
            costs.append((float(np.median([c for c, _ in runs])), int(np.median([m for _, m in runs]))))
        cpu = max(c for c, _ in costs)
        mem = max(m for _, m in costs)
        _NOMINAL[name] = (max(CPU_FACTOR * cpu, CPU_FLOOR_S), max(MEMORY_FACTOR * mem, MEMORY_FLOOR_BYTES))
    return _NOMINAL[name]


def _bombs(cls: type[Message]) -> list[bytes]:
    """Payloads of ``cls`` built to cost: declared sizes without data, huge strings and maps."""
    h = [1, 0, 1, {}]
    default = cls()
    body = [getattr(default, n) for n in cls._body_fields]
    out = []
    names = list(cls._body_fields)
    for k, n in enumerate(names):
        v = body[k]
        if n in ("rows", "cols"):
            out.append(packb([cls.TYPE, cls.VERSION, h, [5000 if j in (names.index("rows"), names.index("cols"))
                                                         else body[j] for j in range(len(body))]]))
        elif isinstance(v, str):
            out.append(packb([cls.TYPE, cls.VERSION, h, body[:k] + ["x" * 1_000_000] + body[k + 1:]]))
        elif isinstance(v, dict):
            out.append(packb([cls.TYPE, cls.VERSION, h, body[:k] + [{f"k{i}": i for i in range(100_000)}] + body[k + 1:]]))
        elif isinstance(v, np.ndarray):
            out.append(packb([cls.TYPE, cls.VERSION, h, body[:k] + [np.zeros(1 << 17)] + body[k + 1:]]))
    out.append(packb([cls.TYPE, cls.VERSION, [1, 0, 1, {f"s{i}": 1 for i in range(50_000)}], body]))
    return out


@st.composite
def _frames(draw, input_types: dict[str, type[Message]], nominal: dict[type[Message], Message]):
    """(input name, payload): valid, corrupted, of another type, random, or a bomb."""
    input_name = draw(st.sampled_from(sorted(input_types)))
    cls = input_types[input_name]
    kind = draw(st.sampled_from(["valid", "valid", "corrupt", "other_type", "random", "bomb"]))
    if kind == "valid":
        return input_name, encode(draw(valid_message(cls)))
    if kind == "corrupt":
        payload = bytearray(encode(nominal[cls]))
        for _ in range(draw(st.integers(1, 8))):
            payload[draw(st.integers(0, len(payload) - 1))] = draw(st.integers(0, 255))
        return input_name, bytes(payload[: draw(st.integers(0, len(payload)))])
    if kind == "other_type":
        other = draw(st.sampled_from([c for c in nominal if c is not cls]))
        return input_name, encode(nominal[other])
    if kind == "random":
        return input_name, draw(st.binary(max_size=2000))
    return input_name, draw(st.sampled_from(_bombs(cls)))


@pytest.fixture(scope="module")
def nominal():
    return _nominal_frames()


@pytest.mark.parametrize("name", sorted(CASES))
def test_every_frame_is_handled_or_rejected_within_its_budget(name, nominal, tmp_path):
    harness = _Harness(CASES[name], tmp_path)
    input_types = {n: i.type for n, i in harness.node.inputs.items()}
    cpu_budget, mem_budget = _budget(name, harness, nominal)
    worst = {"cpu": 0.0, "mem": 0}

    @settings(max_examples=120, deadline=None, derandomize=True,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
    @given(_frames(input_types, nominal))
    def check(frame):
        input_name, payload = frame
        topic = harness.host.input_topics[input_name]
        counters = harness.host.counters
        before = (counters[f"in.{topic}.received"], counters[f"in.{topic}.rejected"])
        try:
            decode(payload, input_types[input_name])
            valid = True
        except DecodeError:
            valid = False
        cpu, mem = harness.feed(input_name, payload)
        assert counters["handler_errors"] == 0, harness.ex.logs[-3:]
        assert counters[f"in.{topic}.received"] == before[0] + 1
        assert counters[f"in.{topic}.rejected"] == before[1] + (0 if valid else 1)
        worst["cpu"], worst["mem"] = max(worst["cpu"], cpu), max(worst["mem"], mem)
        assert cpu <= cpu_budget, f"{cpu * 1e3:.2f} ms CPU for a {len(payload)}-byte frame, budget {cpu_budget * 1e3:.2f} ms"
        assert mem <= mem_budget, f"{mem} bytes allocated for a {len(payload)}-byte frame, budget {mem_budget}"

    try:
        check()
    finally:
        harness.ex.stop()
