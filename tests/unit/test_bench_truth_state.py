"""The bench's split of false alarms and sticking frames by the truth's slip state
(tests/bench/bench_detection.py ``by_truth_state``), on a hand-made run."""

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
from bench_detection import NO_SLIDING, by_truth_state  # noqa: E402

MS = 1_000_000


def _run(share: list[float], gross: list[bool], flag: list[bool], contact: list[bool]) -> tuple[dict, np.ndarray]:
    t = np.arange(len(share), dtype=np.int64) * 10 * MS  # 10 ms frames, truth on the same stamps
    data = {"t": t, "truth_t": t, "gross": np.array(gross), "slip_share": np.array(share, dtype=float),
            "contact": np.array(contact)}
    return data, np.array(flag)


def test_flags_split_by_the_truths_sliding_share_at_the_flagged_frame():
    # frames 0-5 stick: shares 0, tiny (≤ NO_SLIDING), 0.3, 0.3, 0, 0.9; frame 3 out of contact.
    # Every sticking frame is far (≥ 400 ms) from the one gross slip (frames 50-60).
    share = [0.0, NO_SLIDING / 2, 0.3, 0.3, 0.0, 0.9] + [0.0] * 44 + [0.97] * 11 + [0.0] * 50
    gross = [s >= 0.95 for s in share]
    flag = [True, True, True, True, False, True] + [False] * 105
    contact = [True, True, True, False, True, True] + [True] * 105
    data, f = _run(share, gross, flag, contact)
    split = by_truth_state(data, f)
    # no sliding: frames 0, 1 flagged; sticking frames with no sliding: 0, 1, 4, 6-49, 61-110 = 3 + 44 + 50
    # partial: frames 2, 5 flagged (3 not in contact); sticking in partial slip: 2, 5
    assert split == (2, 2, 97, 2)


def test_flags_inside_an_episodes_window_are_not_false_alarms_in_either_state():
    # a gross slip at frames 10-14; the frame just before it (partial slip) and the ones in
    # its release window are excused by lib/episodes, whatever the truth's share there
    share = [0.0] * 9 + [0.5] + [0.97] * 5 + [0.2, 0.0] + [0.0] * 20
    gross = [s >= 0.95 for s in share]
    flag = [False] * 9 + [True] * 8 + [False] * 20
    data, f = _run(share, gross, flag, [True] * len(share))
    false_none, false_partial, stick_none, stick_partial = by_truth_state(data, f)
    assert (false_none, false_partial) == (0, 0)
    assert (stick_none, stick_partial) == (30, 2)
