"""The monitor bounded against what the bus may carry, and naming sensors under attack:
hand-made streams on the in-process executor, the way a launched monitor receives them."""

from __future__ import annotations

import json
import tracemalloc

from slipstack.messages import Diagnostics, Header, RigTruth, encode
from slipstack.nodes.monitor import MAX_OTHER_NODES, Monitor, MonitorParams, check_problems
from slipstack.nodes.runtime.inprocess import InProcessExecutor

S = 1_000_000_000
GRAPH = {"rig", "ft_driver", "tactile_driver", "fusion", "cor_estimator", "slip_detector", "grip_controller",
         "monitor", "recorder"}


def _diag(node: str, t_ns: int, seq: int = 0, **counters: float) -> bytes:
    return encode(Diagnostics(node=node, counters=counters, header=Header(t_ns, seq, t_ns, {})))


def _truth(t_ns: int) -> bytes:
    return encode(RigTruth(f_n_applied=5.0, header=Header(t_ns, t_ns // 1_000_000, t_ns, {})))


def _run(events, tmp_path, graph=GRAPH):
    summary = tmp_path / "summary.json"
    monitor = Monitor(MonitorParams(summary_path=str(summary), status_period_s=1.0), graph_nodes=graph)
    ex = InProcessExecutor([monitor])
    ex.feed(events)
    ex.run()
    ex.stop()
    return json.loads(summary.read_text()), ex.logs, monitor


def _graph_reports(seconds: int, **counters):
    """Every node of the graph reporting each second, and the rig's truth."""
    events = [(k * S, "rig/truth", _truth(k * S)) for k in range(seconds)]
    for k in range(seconds):
        events += [(k * S + 1, "diagnostics", _diag(node, k * S, k, **counters.get(node, {}))) for node in GRAPH]
    return events


def test_a_flood_of_made_up_node_names_stays_bounded_and_is_named(tmp_path):
    """1026 diagnostics frames, each from a new name with 4000 long counters (the attack grew
    the monitor to 600 MB and ~1000 SILENT nodes, and it was killed before its summary)."""
    big = {f"made.up.counter.{'x' * 100}.{k}": 1.0 for k in range(4000)}
    summary = tmp_path / "summary.json"
    monitor = Monitor(MonitorParams(summary_path=str(summary), status_period_s=1.0), graph_nodes=GRAPH)
    ex = InProcessExecutor([monitor])
    events = _graph_reports(10)
    ex.feed([e for e in events if e[0] < 2 * S])
    ex.run()
    tracemalloc.start()
    try:
        for k in range(1026):  # one frame at a time, as the bus hands them over
            ex.feed([(2 * S + k, "diagnostics", _diag(f"intruder{k}", 2 * S, **big))])
            ex.run()
        kept = tracemalloc.get_traced_memory()[0]
    finally:
        tracemalloc.stop()
    ex.feed([e for e in events if e[0] >= 2 * S])
    ex.run()
    ex.stop()
    s, logs = json.loads(summary.read_text()), ex.logs
    assert len(monitor.nodes) == len(GRAPH) + MAX_OTHER_NODES
    assert s["diagnostics_ignored"] == 1026 - MAX_OTHER_NODES
    assert s["silent_nodes"] == {} and s["nodes_that_went_silent"] == {}  # made-up names are no silent nodes
    assert not any("SILENT" in line for line in logs)
    health = [line for line in logs if "HEALTH" in line]
    assert any(f"{1026 - MAX_OTHER_NODES} diagnostics frames from more than {MAX_OTHER_NODES} senders" in line
               for line in health), health
    # kept per sender: at most 512 counters of <= 160 characters (~0.1 MB), not all it sent (~0.6 MB a frame)
    assert kept < 16e6, f"{kept / 1e6:.0f} MB"


def test_a_graph_node_that_stops_reporting_is_still_silent(tmp_path):
    events = [e for e in _graph_reports(10) if not (e[1] == "diagnostics" and b"fusion" in e[2] and e[0] > 3 * S)]
    s, _, _ = _run(events, tmp_path)
    assert list(s["silent_nodes"]) == ["fusion"]


def test_forged_device_data_and_an_implausible_ft_sensor_are_named(tmp_path):
    """The F/T driver rejected 595 KB of garbage RDT datagrams and dropped forged records, and
    fusion found the F/T sensor reading far below the pad (a BIAS under load): HEALTH said ok."""
    counters = {"ft_driver": {"device.rejected_bytes": 595_000, "device.implausible_records": 120,
                              "device.frames": 5000},
                "fusion": {"fusion.samples": 5000, "in.ft/wrench.received": 5000, "fusion.implausible_ft": 2400}}
    s, logs, _ = _run(_graph_reports(10, **counters), tmp_path)
    health = "\n".join(line for line in logs if "HEALTH" in line)
    assert ("ft_driver's device link carried data that is no valid sample (records out of the stream 120, bytes "
            "rejected 595000): forged") in health, health
    assert "the F/T sensor read implausibly low against the pad in 2400 of 5000 samples" in health, health
    assert s["device_rejects"] == {"ft_driver": {"implausible_records": 120, "rejected_bytes": 595000}}
    assert s["ft_samples"]["implausible"] == 2400
    reported = [x for x in check_problems(s, MonitorParams()) if "device link" in x or "F/T sensor" in x]
    assert reported == []  # reported only: they do not fail the run's check


def test_a_clean_driver_says_nothing(tmp_path):
    s, logs, _ = _run(_graph_reports(5, ft_driver={"device.frames": 5000, "device.rejected_bytes": 0}), tmp_path)
    assert s["device_rejects"] == {}
    assert "[monitor] HEALTH: ok" in logs, [line for line in logs if "HEALTH" in line]
