"""Must show 5 on the real stack: a recording made while the stack runs replays into
a single node in isolation and reproduces that node's recorded outputs exactly.

More in docs/modules.md, `tests/e2e/test_stack_replay.py`.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from slipstack.launch.launch_file import launch_files_dir, load_launch_file
from slipstack.messages import Contact, Slip, decode
from slipstack.nodes.recording.bag_io import (RecordedFrame, RecordingWriter, clock_offset_ns, match_outputs, read_recording,
                                    recording_info, replay_into)

pytestmark = pytest.mark.e2e

# fig15 shortened to 2.5 s: a 0.3 s hold, then a pull that makes it slip within 1 s.
SEGMENTS = """
[[disturbance.segments]]
kind = "hold"
duration_s = 0.3
[[disturbance.segments]]
kind = "ramp"
duration_s = 0.7
force_N = [0.0, 1.8]
[[disturbance.segments]]
kind = "hold"
duration_s = 1.5
"""


def short_fig15(folder: Path) -> Path:
    """A copy of the shipped fig15 scene, 2.5 s long, with an early pull."""
    text = (launch_files_dir().parent / "scenes" / "fig15.toml").read_text()
    head = text.split("[[disturbance.segments]]")[0]
    head, n = re.subn(r"(?m)^duration_s = .*$", "duration_s = 2.5", head, count=1)
    assert n == 1, "fig15.toml has no top-level duration_s"
    path = folder / "fig15_short.toml"
    path.write_text(head + SEGMENTS)
    return path


def _load_key(msg: Contact | Slip) -> tuple:
    """What a ``slip`` copies from its ``contact``: stamps and the load (f_n, f_t, τ)."""
    return (msg.header.stamp_ns, tuple(sorted(msg.header.sources.items())), msg.f_n, tuple(msg.f_t.tolist()), msg.tau)


def handled_contacts(contacts: list[RecordedFrame], slips: list[Slip]) -> list[RecordedFrame]:
    """The contact frames the live detector handled: those its ``slip`` outputs, in order, derive from."""
    keys = iter([_load_key(s) for s in slips])
    want = next(keys, None)
    handled = []
    for f in contacts:
        if _load_key(decode(f.payload)) == want:
            handled.append(f)
            want = next(keys, None)
    return handled


def test_recorded_contact_replays_into_slip_detector_exactly(launch, run_root):
    scene = short_fig15(run_root)
    recording = run_root / "stack.mcap"
    # record_topics:= (empty) records every topic; `record_topics:=[]` would record a topic named "[]".
    args = [f"scene:={scene}", "record:=true", f"recording:={recording}", "record_topics:=", "monitor:=false",
            "controller:=false"]
    graph = launch("fig15", *args)
    assert graph.wait_exit(100) == 0, graph.log()  # in run time: a hang shows its log before the test's timeout

    info = recording_info(recording)
    assert info.finished, info
    assert {"contact", "slip", "cor"} <= set(info.topics), info.topics
    contacts = info.topics["contact"]
    assert contacts.seq_gaps == 0 and contacts.first_seq == 0, contacts  # from the first sample on

    # The node the launch ran, with the parameters the launch gave it.
    launched = load_launch_file("fig15", dict(a.split(":=", 1) for a in args), builtins={"run_dir": "/unused"})
    (entry,) = [e for e in launched.nodes if e.name == "slip_detector"]
    detector = entry.instance()

    recorded = [decode(f.payload) for f in read_recording(recording, ["slip"])]
    every_contact = list(read_recording(recording, ["contact"]))
    handled = handled_contacts(every_contact, recorded)
    # every slip the detector published (by its last diagnostics report) is in the recording, and
    # came from a contact it handled; a batch of contacts gives one verdict (nodes/slip_detector.py),
    # so how many contacts each verdict covers depends on the machine's load
    (last_report,) = [m for m in map(decode, (f.payload for f in read_recording(recording, ["diagnostics"])))
                      if m.node == "slip_detector"][-1:]
    counted = last_report.counters
    accepted = (counted["in.contact.received"] - counted.get("in.contact.dropped", 0)
                - counted.get("in.contact.rejected", 0))
    published = counted["out.slip.published"]
    assert len(handled) == len(recorded) == published >= 1, (len(handled), len(recorded), published, contacts.count)
    assert accepted >= published, (accepted, published)
    # Replayed: every contact from the first judged to the last, in order. Under load the live
    # detector's batch input folds a contact into the next one's verdict (nodes/slip_detector.py):
    # that contact gave no verdict of its own but did move the detector's state, so the replay
    # hands it over too (one verdict more each), and only the folded verdict itself may differ.
    stamps = [decode(f.payload).header.stamp_ns for f in every_contact]
    judged = {decode(f.payload).header.stamp_ns for f in handled}
    first, last = stamps.index(min(judged)), stamps.index(max(judged))
    fed = every_contact[first:last + 1]
    folded = {t for before, t in zip(stamps[first:last], stamps[first + 1:last + 1]) if t in judged and before not in judged}
    assert len(fed) - len(handled) <= counted["in.contact.received"] - published, (len(fed), len(handled), counted)
    inputs = run_root / "handled_contacts.mcap"
    with RecordingWriter(inputs, wall_minus_monotonic_ns=clock_offset_ns(recording)) as writer:
        for f in fed:
            writer.write(f.topic, f.payload, f.log_time_ns)

    replayed = replay_into(detector, inputs)["slip"]
    result = match_outputs(recorded, replayed)
    unexplained = [m for m in result.mismatches if m[0] not in folded]
    assert unexplained == [], unexplained[:5]
    assert result.only_replayed == len(fed) - len(handled), result
    assert result.matched == len(recorded) and result.only_recorded == 0, result
    states = {m.state for m in recorded}
    assert "stick" in states and states & {"translation", "rotation", "combined"}, states  # it saw a slip
