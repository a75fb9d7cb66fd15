"""Episode matching, checked by hand on tiny streams."""

import numpy as np

from slipstack.lib.episodes import Episode, detection_quality, find_episodes

MS = 1_000_000


def test_episodes_are_maximal_runs_and_close_ones_merge():
    t = np.arange(10) * MS
    s = np.array([0, 1, 1, 0, 1, 0, 0, 0, 1, 1], bool)
    assert find_episodes(t, s) == [Episode(1 * MS, 2 * MS), Episode(4 * MS, 4 * MS), Episode(8 * MS, 9 * MS)]
    assert find_episodes(t, s, min_gap_ns=3 * MS) == [Episode(1 * MS, 4 * MS), Episode(8 * MS, 9 * MS)]


def test_delay_missed_and_false_slip_by_hand():
    t = np.arange(200) * MS
    s = np.zeros(200, bool)
    s[50:60] = True   # episode A at 50 ms
    s[150:160] = True  # episode B at 150 ms, never flagged
    vt = t.copy()
    vs = np.zeros(200, bool)
    vs[52] = True      # A detected 2 ms late
    vs[100] = True     # a false slip, far from both episodes
    q = detection_quality(t, s, vt, vs, lead_ns=5 * MS, grace_ns=5 * MS)
    assert q.delays_ns == (2 * MS,) and q.missed == 1
    # windows: A covers 45..64 (20 frames), B covers 145..164 (20 frames) -> 160 stick frames
    assert q.stick_frames == 160 and q.false_slip_frames == 1
    assert q.false_slip_rate == 1 / 160
    assert q.delay_percentile_ms(50) == 2.0


def test_incipient_frames_are_not_counted_as_sticking():
    t = np.arange(100) * MS
    s = np.zeros(100, bool)
    inc = np.zeros(100, bool)
    inc[10:20] = True  # partial slip, never gross
    vs = np.zeros(100, bool)
    vs[15] = True      # an early warning during partial slip
    q = detection_quality(t, s, t, vs, incipient=inc)
    assert q.stick_frames == 90 and q.false_slip_frames == 0 and q.episodes == ()
