"""Offline and online agree: a golden recording's contacts replayed through the library
detector (lib/detector.py) and through the slip_detector node (in-process executor)
give the same verdict on every frame, and both give the recorded one (states, stamps and
statuses exactly, floats within ``same_value``'s stated tolerance: docs/portability.md §1)."""

from __future__ import annotations

import pytest
from golden_config import GOLDENS, Golden, build_node

from slipstack.lib.detector import Detector, DetectorSettings
from slipstack.messages import Contact, Slip, decode
from slipstack.nodes.recording.bag_io import read_recording, replay_into, same_value
from slipstack.nodes.material_param import resolve_material


def _library_settings(golden: Golden) -> DetectorSettings:
    """The golden's node parameters, spelled as library settings (release_ms → ns)."""
    params = dict(golden.slip)
    if "release_ms" in params:
        params["release_ns"] = round(params.pop("release_ms") * 1e6)
    return DetectorSettings.from_material(resolve_material("rubber"), **params)


def _row(stamp_ns: int, state: str, gamma: float, margin: float, status: str, p_c: tuple | None,
         verdicts: dict) -> tuple:
    return stamp_ns, state, gamma, margin, status, p_c, {k: (bool(s), float(m)) for k, (s, m) in verdicts.items()}


def _message_row(m: Slip) -> tuple:
    p_c = (float(m.p_c[0]), float(m.p_c[1])) if m.p_c_valid else None
    return _row(m.header.stamp_ns, m.state, m.gamma, m.margin, m.status, p_c, m.verdicts)


@pytest.mark.parametrize("golden", GOLDENS, ids=[g.name for g in GOLDENS])
def test_library_detector_matches_the_node_frame_by_frame(golden: Golden) -> None:
    detector = Detector(_library_settings(golden))
    library = []
    for frame in read_recording(golden.path, ["contact"]):
        contact: Contact = decode(frame.payload)
        v = detector.step(contact, contact.header.stamp_ns, tactile_frame=contact.header.sources.get("tactile"))
        p_c = (float(v.p_c[0]), float(v.p_c[1])) if v.p_c is not None else None
        library.append(_row(v.t_ns, v.state, v.gamma, v.margin, v.status, p_c, v.verdicts))
    node = [_message_row(m) for m in replay_into(build_node(golden, "slip_detector"), golden.path)["slip"]]
    recorded = [_message_row(decode(f.payload)) for f in read_recording(golden.path, ["slip"])]

    assert len(library) == len(node) == len(recorded) > 50
    for k, (mine, theirs, rec) in enumerate(zip(library, node, recorded)):
        assert same_value(mine, theirs), f"frame {k}: library {mine} != node {theirs}"
        assert same_value(mine, rec), f"frame {k}: library {mine} != recorded {rec}"
    states = {row[1] for row in library}
    assert "stick" in states and states & {"translation", "rotation", "combined"}, states  # the latch was exercised
