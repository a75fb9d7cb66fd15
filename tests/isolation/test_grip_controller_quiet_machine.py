"""The grip controller names the machine its stale inputs come from (a graph over several
machines: the launcher hands it ``$SLIPSTACK_REMOTE_SOURCES``), and only then."""

from __future__ import annotations

import json

import numpy as np
import pytest

from slipstack.messages import Header, Slip, decode
from slipstack.nodes.grip_controller import GripController, GripControllerParams
from slipstack.nodes.runtime.inprocess import InProcessExecutor
from slipstack.nodes.runtime.remote_sources import REMOTE_SOURCES_ENV

MS = 1_000_000
ROBOT = "machine robot, 127.0.0.1"


def _slip(k: int, status: str = "ok") -> Slip:
    """A verdict received and stamped at ``k`` ms: 0.9 N along x on 4 N, mu 0.45."""
    return Slip(state="stick", margin=0.5, method="exact", gamma=0.5, status=status, f_n=4.0,
                f_t=np.array([0.9, 0.0]), tau=0.0, p_c=np.zeros(2), header=Header(k * MS, k, k * MS, {}))


def _status(events, until_ms: int) -> str:
    """The controller's status line on ``diagnostics`` after ``events``, at ``until_ms``."""
    ex = InProcessExecutor([GripController(GripControllerParams(law="exact", timeout_ms=20.0))])
    ex.feed(events)
    ex.run(until_ns=until_ms * MS)
    return decode(ex.host("grip_controller").diagnostics()).status


@pytest.fixture
def robot_sources(monkeypatch):
    monkeypatch.setenv(REMOTE_SOURCES_ENV, json.dumps({"slip": ROBOT, "ft/wrench": ROBOT}))


def test_inputs_gone_stale_name_the_machine_they_come_from(robot_sources):
    status = _status([(k * MS, "slip", _slip(k)) for k in range(1, 11)], until_ms=200)
    assert status.startswith("fail-safe: ") and status.endswith(f"(from {ROBOT})"), status


def test_a_fresh_verdict_that_is_not_ok_blames_no_machine(robot_sources):
    status = _status([(k * MS, "slip", _slip(k, "stale" if k > 5 else "ok")) for k in range(1, 11)], until_ms=10)
    assert status == "fail-safe: input status not ok"


def test_on_one_machine_the_status_names_none(monkeypatch):
    monkeypatch.delenv(REMOTE_SOURCES_ENV, raising=False)
    status = _status([(k * MS, "slip", _slip(k)) for k in range(1, 11)], until_ms=200)
    assert status.startswith("fail-safe: input age") and "machine" not in status, status


def test_a_malformed_map_is_refused_before_the_node_runs(monkeypatch):
    from slipstack.lib.errors import ConfigError

    monkeypatch.setenv(REMOTE_SOURCES_ENV, "[1, 2]")
    with pytest.raises(ConfigError, match="JSON object topic"):
        GripController()


@pytest.mark.parametrize("sources, named", [
    ({"left/slip": ROBOT}, True),  # the remapped topic comes from the robot: missed before
    ({"slip": ROBOT}, False),  # another node's `slip` does; this controller's input is local
])
def test_a_remapped_input_is_looked_up_by_the_topic_it_listens_to(monkeypatch, sources, named):
    """A launch file that remaps the controller's input (``remap = {slip = "left/slip"}``, two
    fingers on one graph): the machine is the one its data on ``left/slip`` comes from."""
    monkeypatch.setenv(REMOTE_SOURCES_ENV, json.dumps(sources))
    ex = InProcessExecutor([GripController(GripControllerParams(law="exact", timeout_ms=20.0))],
                           remaps={"grip_controller": {"slip": "left/slip"}})
    ex.feed([(k * MS, "left/slip", _slip(k)) for k in range(1, 11)])
    ex.run(until_ns=200 * MS)
    status = decode(ex.host("grip_controller").diagnostics()).status
    assert status.startswith("fail-safe: input age"), status
    assert status.endswith(f"(from {ROBOT})") == named and ("machine" in status) == named, status
