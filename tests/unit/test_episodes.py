"""Episode matching, checked by hand on tiny streams."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from slipstack.lib.episodes import Episode, EpisodeTracker, detection_quality, find_episodes

MS = 1_000_000


def test_episodes_are_maximal_runs_and_close_ones_merge():
    t = np.arange(10) * MS
    s = np.array([0, 1, 1, 0, 1, 0, 0, 0, 1, 1], bool)
    assert find_episodes(t, s) == [Episode(1 * MS, 2 * MS), Episode(4 * MS, 4 * MS), Episode(8 * MS, 9 * MS)]
    assert find_episodes(t, s, min_gap_ns=3 * MS) == [Episode(1 * MS, 4 * MS), Episode(8 * MS, 9 * MS)]


def test_delay_missed_and_flag_without_slip_by_hand():
    t = np.arange(200) * MS
    s = np.zeros(200, bool)
    s[50:60] = True   # episode A at 50 ms
    s[150:160] = True  # episode B at 150 ms, never flagged
    vt = t.copy()
    vs = np.zeros(200, bool)
    vs[52] = True      # A detected 2 ms late
    vs[100] = True     # a flag without true slip, far from both episodes
    q = detection_quality(t, s, vt, vs, lead_ns=5 * MS, grace_ns=5 * MS)
    assert q.delays_ns == (2 * MS,) and q.missed == 1
    # windows: A covers 45..64 (20 frames), B covers 145..164 (20 frames) -> 160 stick frames
    assert q.stick_frames == 160 and q.flag_without_slip_frames == 1
    assert q.flag_without_slip_share == 1 / 160
    assert q.delay_percentile_ms(50) == 2.0


def test_a_flag_already_up_when_the_window_opens_is_no_delay():
    """Episode A at 300 ms with the flag up since 100 ms (before A's window opens at 200 ms):
    detected, but no delay (it would read -100 ms, the window's cut-off). Episode B at
    700 ms with the flag raised at 650 ms: a delay of -50 ms, measured."""
    t = np.arange(1000) * MS
    s = np.zeros(1000, bool)
    s[300:320] = True
    s[700:720] = True
    vs = np.zeros(1000, bool)
    vs[100:330] = True
    vs[650:730] = True
    for q in (detection_quality(t, s, t, vs),
              _streamed(t, s, t, vs, np.zeros(1000, bool), [True, False] * 1000).quality()):
        assert q.already_flagged == 1 and q.delays_ns == (-50 * MS,) and q.missed == 0
        assert q.detected == 2


def test_incipient_frames_are_not_counted_as_sticking():
    t = np.arange(100) * MS
    s = np.zeros(100, bool)
    inc = np.zeros(100, bool)
    inc[10:20] = True  # partial slip, never gross
    vs = np.zeros(100, bool)
    vs[15] = True      # an early warning during partial slip
    q = detection_quality(t, s, t, vs, incipient=inc)
    assert q.stick_frames == 90 and q.flag_without_slip_frames == 0 and q.episodes == ()


# -- the streamed tracker against the whole-recording function ------------------------------

def _streamed(t, s, vt, vs, inc, order, **windows) -> EpisodeTracker:
    """Feed the two streams interleaved as ``order`` says (True: next truth sample)."""
    tracker = EpisodeTracker(**windows)
    i = j = 0
    for take_truth in order:
        if take_truth and i < len(t):
            tracker.add_truth(int(t[i]), bool(s[i]), bool(inc[i]))
            i += 1
        elif j < len(vt):
            tracker.add_verdict(int(vt[j]), bool(vs[j]))
            j += 1
    for k in range(i, len(t)):
        tracker.add_truth(int(t[k]), bool(s[k]), bool(inc[k]))
    for k in range(j, len(vt)):
        tracker.add_verdict(int(vt[k]), bool(vs[k]))
    tracker.finish()
    return tracker


@st.composite
def streams(draw):
    n = draw(st.integers(0, 120))
    t = np.cumsum(draw(hnp.arrays(np.int64, n, elements=st.integers(1, 4)))) * MS
    s = draw(hnp.arrays(bool, n))
    inc = draw(hnp.arrays(bool, n))
    m = draw(st.integers(0, 120))
    vt = np.cumsum(draw(hnp.arrays(np.int64, m, elements=st.integers(0, 4)))) * MS
    vs = draw(hnp.arrays(bool, m))
    order = draw(st.lists(st.booleans(), max_size=n + m))
    return t, s, inc, vt, vs, order


@given(streams(), st.sampled_from([(5, 5, 2), (100, 50, 20), (3, 1, 2)]))
@settings(max_examples=300)
def test_streamed_tracker_equals_detection_quality(data, windows_ms):
    t, s, inc, vt, vs, order = data
    lead, grace, gap = (w * MS for w in windows_ms)
    ref = detection_quality(t, s, vt, vs, lead_ns=lead, grace_ns=grace, min_gap_ns=gap, incipient=inc)
    tracker = _streamed(t, s, vt, vs, inc, order, lead_ns=lead, grace_ns=grace, min_gap_ns=gap)
    assert tracker.quality() == ref
    assert (tracker.episode_count, tracker.detected, tracker.missed) == (len(ref.episodes), ref.detected, ref.missed)
    assert tracker.already_flagged == ref.already_flagged


def test_tracker_memory_stays_bounded_over_a_long_stream():
    """200 000 truth samples and verdicts with an episode every second: the tracker
    keeps a few hundred samples however long the stream (counts checked by hand)."""
    tracker = EpisodeTracker(max_kept=50)
    most = 0
    for k in range(200_000):
        stamp = k * MS
        gross = 500 <= k % 1000 < 520  # 20 ms of gross slip each second
        tracker.add_truth(stamp, gross, False)
        tracker.add_verdict(stamp, 495 <= k % 1000 < 525)  # flagged 5 ms early to 5 ms late
        most = max(most, len(tracker._truth) + len(tracker._pending) + len(tracker._open))
    tracker.finish()
    q = tracker.quality()
    assert tracker.episode_count == tracker.detected == 200 and tracker.missed == 0
    assert len(q.episodes) == len(q.delays_ns) == 50 and set(q.delays_ns) == {-5 * MS}
    assert q.flag_without_slip_frames == 0 and q.stick_frames == 200 * (1000 - 170)  # 170 ms window per episode
    assert most < 300, most
