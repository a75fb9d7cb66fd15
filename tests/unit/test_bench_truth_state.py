"""The bench's split of false alarms and sticking frames by the truth's slip state
(tests/bench/bench_detection.py ``by_truth_state``, ``above_own_onsets``, ``followed_by_slip``), on
hand-made runs."""

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
from bench_detection import NO_SLIDING, above_own_onsets, by_truth_state, followed_by_slip  # noqa: E402

from slipstack.lib.material import Material  # noqa: E402

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


def test_the_oracle_threshold_counts_stuck_frames_at_or_above_the_runs_own_onset_per_load_kind():
    # 100 frames of 10 ms; a gross slip at frames 60-64 whose onset (frame 59) is a pull at
    # γ 0.9 on a flat face (spread 0.05). γ noise 0.01: the oracle's threshold is 0.9 − 0.03.
    n = 100
    gamma, share = np.full(n, 0.1), np.zeros(n)
    f_t, tau, spread = np.tile([1.0, 0.0], (n, 1)), np.zeros(n), np.full(n, 0.05)
    gamma[10:30] = 0.88          # 10-19 a pull, no sliding: above, of the onset's kind
    f_t[20:25], tau[20:25] = 0.0, 1.0  # 20-24 a twist: above, another kind
    share[25:30] = 0.3           # 25-29 a pull in partial slip: above, its kind
    gamma[30:35] = 0.86          # under the threshold
    gamma[35:40], spread[35:40] = 0.88, 0.3  # a pull on another pressure spread: another kind
    gamma[59], share[60:65] = 0.9, 0.97
    t = np.arange(n, dtype=np.int64) * 10 * MS
    data = {"t": t, "truth_t": t, "gross": share >= 0.95, "slip_share": share, "contact": np.ones(n, dtype=bool),
            "gamma": gamma, "f_t": f_t, "tau": tau, "spread": spread}
    material = Material("hand", mu_s=0.45, mu_d=0.36, beta_s_m=0.002, gamma_noise_stick=0.01)
    onsets = [(0.9, 0.0, 0.05)]
    assert above_own_onsets(data, onsets, material, by_kind=False) == (20, 5)
    assert above_own_onsets(data, onsets, material, by_kind=True) == (10, 5)
    assert above_own_onsets(data, [], material, by_kind=True) == (0, 0)


def test_flags_followed_by_a_gross_slip_within_half_a_second_are_counted_by_the_truths_state():
    # 10 ms frames; a gross slip at frames 60-64 (onset 600 ms; window 580-665 ms: frames 58-66).
    # Partial slip at frames 5-14, flagged: 10-14 lie within 500 ms of the onset, 5-9 do not.
    # Flags at 70-74 with no sliding, after the slip: nothing follows them.
    share = [0.0] * 5 + [0.3] * 10 + [0.0] * 45 + [0.97] * 5 + [0.0] * 35
    flag = [False] * 5 + [True] * 10 + [False] * 55 + [True] * 5 + [False] * 25
    data, f = _run(share, [s >= 0.95 for s in share], flag, [True] * len(share))
    counts = followed_by_slip(data, f)
    # partial: flagged 10 (5 followed), all 10 (5); no sliding: flagged 5 (0), all 0-4, 15-57, 67-99 = 81 (15-57: 43)
    assert counts.tolist() == [10, 5, 10, 5, 5, 0, 81, 43]
