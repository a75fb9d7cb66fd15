"""Every processing node against recorded inputs and recorded expected outputs.

The golden recordings (``golden/*.mcap``, described in ``golden_config.py``) hold
every topic of the whole stack run in lock-step from simulated time 0. Each node is
built fresh with the recording's parameters, fed its input topics from the file
(``replay_into``: each frame at its recorded publication time, in recorded order) and
must reproduce every recorded output exactly — as :func:`match_outputs` compares
them, and byte for byte on the wire (header seq and pub_ns included), since the
replay starts where the recording did.

Regenerate after an intended behaviour change (and review the diff it causes)::

    .venv/bin/python tests/isolation/make_golden.py

``test_golden_files_are_fresh`` regenerates them into a temporary folder and compares
frame by frame (``make_golden.py --check`` does the same from the command line).
"""

from __future__ import annotations

from pathlib import Path

import pytest
from golden_config import GOLDENS, NODES, Golden, build_node
from make_golden import compare_recordings, write_golden

from slipstack.messages import decode, encode
from slipstack.nodes.bag_io import match_outputs, read_recording, replay_into

CASES = [(g, n) for g in GOLDENS for n in NODES if g.tactile or n != "cor_estimator"]


@pytest.mark.parametrize(("golden", "node_name"), CASES, ids=[f"{g.name}-{n}" for g, n in CASES])
def test_node_reproduces_recorded_outputs(golden: Golden, node_name: str) -> None:
    node = build_node(golden, node_name)
    replayed = replay_into(node, golden.path)
    for output in node.outputs.values():
        frames = list(read_recording(golden.path, [output.topic]))
        recorded = [decode(f.payload) for f in frames]
        mine = replayed.get(output.topic, [])
        result = match_outputs(recorded, mine)
        assert result.mismatches == [], result.mismatches[:5]
        assert result.matched == len(recorded) == len(mine) > 50, result
        assert [encode(m) for m in mine] == [f.payload for f in frames]


def test_goldens_cover_slip_onset_and_the_grip_reaction() -> None:
    """The recordings exercise what state a node keeps: a slip onset, the latch, a grip rise."""
    for g in GOLDENS:
        slips = [decode(f.payload) for f in read_recording(g.path, ["slip"])]
        grips = [decode(f.payload).f_n_desired for f in read_recording(g.path, ["grip/command"])]
        states = [m.state for m in slips]
        onset = next(k for k, s in enumerate(states) if s in ("translation", "rotation", "combined"))
        assert states[onset - 1] == "stick", g.name
        assert max(grips[onset:]) > grips[onset - 1] + 1.0, g.name  # the law raised the grip by > 1 N
    tactile = next(g for g in GOLDENS if g.tactile)
    cases = {decode(f.payload).case for f in read_recording(tactile.path, ["cor"])}
    assert {"rotation", "none"} <= cases or {"on-taxel", "none"} <= cases, cases


def test_golden_files_are_fresh(tmp_path: Path) -> None:
    for g in GOLDENS:
        write_golden(g, tmp_path / g.path.name)
        diffs = compare_recordings(g.path, tmp_path / g.path.name)
        assert diffs == [], f"{g.path} is stale (run tests/isolation/make_golden.py): {diffs[:3]}"
