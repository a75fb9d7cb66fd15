"""Scoring flags against the truth (analysis/replay.py), by hand: missed, delay of the flag's rise
(negative: a warning), false alarms outside every window, the latch's hold apart; and the
latch over kept load factors with a μ error."""

from __future__ import annotations

import numpy as np

from slipstack.analysis.replay import LEAD_NS, MARGIN_NS, FrameGammas, latch_flags, score_flags
from slipstack.lib.detection import DetectorConfig

MS = 1_000_000
RELEASE_NS = 20 * MS
T = np.arange(0, 1000) * MS  # 1 kHz frames and truth, 1 s


def truth(*episodes: tuple[int, int]) -> np.ndarray:
    """Gross slip over [start, end] ms for each episode."""
    gross = np.zeros(T.size, dtype=bool)
    for a, b in episodes:
        gross[a:b + 1] = True
    return gross


def flags(*runs: tuple[int, int]) -> np.ndarray:
    f = np.zeros(T.size, dtype=bool)
    for a, b in runs:
        f[a:b + 1] = True
    return f


def score(gross: np.ndarray, flag: np.ndarray, in_contact: np.ndarray | None = None):
    return score_flags(T, gross, T, flag, np.ones(T.size, dtype=bool) if in_contact is None else in_contact,
                       RELEASE_NS)


def test_a_flag_before_the_onset_is_a_warning_with_its_rise_as_delay():
    # slip 500–600 ms; the flag rises at 470 ms (30 ms early) and falls at 610 ms
    q = score(truth((500, 600)), flags((470, 610)))
    assert (q.episodes, q.missed, q.delays_ns) == (1, 0, (-30 * MS,))
    # the 10 flagged frames 470–479 lie before the window (onset − 20 ms): false alarms; the
    # rest lies inside [onset − 20 ms, end + release + margin]
    assert q.false_alarm_frames == 10 and q.latch_hold_frames == 0
    assert q.stick_frames == T.size - 101


def test_a_late_flag_and_a_missed_episode():
    gross = truth((200, 260), (500, 600))
    q = score(gross, flags((215, 300)))  # 15 ms late on the first, nothing on the second
    assert (q.missed, q.delays_ns) == (1, (15 * MS,))
    # the flag held past 260 + 20 + 5 ms: 286–300 is the latch holding on for the first episode
    end = 260 * MS + RELEASE_NS + MARGIN_NS
    held = int(np.count_nonzero((T > end) & (T <= 300 * MS)))
    assert q.false_alarm_frames == held == q.latch_hold_frames


def test_a_flag_only_after_the_episode_detects_nothing_and_one_far_from_slip_is_a_false_alarm():
    gross = truth((500, 600))
    q = score(gross, flags((601, 610), (800, 809)))
    assert q.missed == 1 and q.delays_ns == ()
    assert q.false_alarm_frames == 10 and q.latch_hold_frames == 0  # 601–610 lies in the excused window


def test_frames_without_contact_are_not_sticking_frames():
    gross = truth((500, 600))
    off = np.ones(T.size, dtype=bool)
    off[:100] = False
    q = score(gross, flags((0, 9)), off)
    assert q.false_alarm_frames == 0 and q.stick_frames == T.size - 101 - 100


def test_the_flag_window_opens_lead_before_the_onset():
    gross = truth((500, 600))
    early = score(gross, flags((500 - LEAD_NS // MS, 500 - LEAD_NS // MS)))
    assert early.missed == 0 and early.delays_ns == (-LEAD_NS,)
    too_early = score(gross, flags((500 - LEAD_NS // MS - 1, 500 - LEAD_NS // MS - 1)))
    assert too_early.missed == 1


def test_the_latch_over_kept_load_factors_and_a_mu_error():
    """γ rises through the band edge 1 − δ = 0.9 at frame 5; with μ 10 % too high the test's γ is
    γ/1.1, which reaches the edge only where γ ≥ 0.99 (frame 7)."""
    gamma = np.array([0.5, 0.7, 0.8, 0.85, 0.88, 0.92, 0.95, 0.995, 1.0, 1.0])
    frames = FrameGammas("exact", np.arange(10) * MS, gamma, np.ones(10, dtype=bool), 0.0)
    config = DetectorConfig(delta=0.1, gamma_release=0.5, onset_frames=1)
    assert latch_flags(frames, config).tolist() == [False] * 5 + [True] * 5
    assert latch_flags(frames, config, mu_error=0.1).tolist() == [False] * 7 + [True] * 3
    with_gap = FrameGammas("exact", frames.t_ns, np.where(np.arange(10) == 6, np.nan, gamma), frames.in_contact, 0.0)
    assert latch_flags(with_gap, config).tolist() == [False] * 5 + [True] * 5  # no verdict keeps the flag
    # μ 10 % too low: γ/0.9 reaches the edge from 0.85 (0.944) on, 0.8 (0.889) stays below
    assert latch_flags(frames, config, mu_error=-0.1).tolist() == [False] * 3 + [True] * 7
