"""Episode matching (docs/math.md §3.2), checked by hand on tiny streams."""

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


def _both(t, s, vt, vs, **windows):
    """The whole-recording result and the streamed one (truth and verdicts alternated)."""
    order = [True, False] * (len(t) + len(vt))
    return detection_quality(t, s, vt, vs, **windows), _streamed(t, s, vt, vs, order, **windows).quality()


def test_delay_missed_false_alarms_and_latch_hold_by_hand():
    """1 ms frames; episode A 100–119 ms, flagged 102–149 ms (the latch held 30 ms past
    its end); episode B 300–309 ms, never flagged; one flag at 200 ms in between. A's
    window runs 80–144 ms (20 ms before, 20 ms release dwell + 5 ms after): 145–149 are
    latch hold, 200 a plain false alarm. Sticking frames: 400 − 30 sliding."""
    t = np.arange(400) * MS
    s = np.zeros(400, bool)
    s[100:120] = True
    s[300:310] = True
    vs = np.zeros(400, bool)
    vs[102:150] = True
    vs[200] = True
    for q in _both(t, s, t, vs):
        assert q.delays_ns == (2 * MS,) and q.missed == 1 and q.detected == 1
        assert q.holds_ns == (31 * MS,)  # the first frame down is 150 ms, 31 ms after the last sliding one
        assert q.stick_frames == 370 and q.false_alarm_frames == 6 and q.latch_hold_frames == 5
        assert q.false_alarm_share == 6 / 370 and q.latch_hold_share == 5 / 370
        assert q.delay_percentile_ms(50) == 2.0 and q.hold_percentile_ms(50) == 31.0


def test_a_flag_raised_long_before_the_onset_is_an_early_delay_and_false_alarms_before():
    """Episode at 300 ms; the flag up from 100 ms: the delay is -200 ms (a warning that
    early), and the flagged sticking frames before the window (100–279 ms) are false alarms."""
    t = np.arange(1000) * MS
    s = np.zeros(1000, bool)
    s[300:320] = True
    vs = np.zeros(1000, bool)
    vs[100:330] = True
    for q in _both(t, s, t, vs):
        assert q.delays_ns == (-200 * MS,) and q.missed == 0
        assert q.false_alarm_frames == 180 and q.latch_hold_frames == 0
        assert q.holds_ns == (11 * MS,)


def test_a_flag_only_after_the_episode_ended_is_a_miss():
    t = np.arange(200) * MS
    s = np.zeros(200, bool)
    s[50:60] = True
    vs = np.zeros(200, bool)
    vs[61:64] = True  # inside the release window: not a false alarm, not a detection either
    for q in _both(t, s, t, vs):
        assert q.missed == 1 and q.delays_ns == () and q.false_alarm_frames == 0


def test_frames_without_contact_are_not_sticking_frames():
    t = np.arange(100) * MS
    s = np.zeros(100, bool)
    contact = np.ones(100, bool)
    contact[:40] = False
    q = detection_quality(t, s, t, np.zeros(100, bool), in_contact=contact)
    assert q.stick_frames == 60


# -- the streamed tracker against the whole-recording function ------------------------------

def _streamed(t, s, vt, vs, order, contact=None, **windows) -> EpisodeTracker:
    """Feed the two streams interleaved as ``order`` says (True: next truth sample)."""
    tracker = EpisodeTracker(**windows)
    contact = np.ones(len(vt), bool) if contact is None else contact
    i = j = 0
    for take_truth in order:
        if take_truth and i < len(t):
            tracker.add_truth(int(t[i]), bool(s[i]))
            i += 1
        elif j < len(vt):
            tracker.add_verdict(int(vt[j]), bool(vs[j]), bool(contact[j]))
            j += 1
    for k in range(i, len(t)):
        tracker.add_truth(int(t[k]), bool(s[k]))
    for k in range(j, len(vt)):
        tracker.add_verdict(int(vt[k]), bool(vs[k]), bool(contact[k]))
    tracker.finish()
    return tracker


@st.composite
def streams(draw):
    n = draw(st.integers(0, 120))
    t = np.cumsum(draw(hnp.arrays(np.int64, n, elements=st.integers(1, 4)))) * MS
    s = draw(hnp.arrays(bool, n))
    m = draw(st.integers(0, 120))
    vt = np.cumsum(draw(hnp.arrays(np.int64, m, elements=st.integers(0, 4)))) * MS
    vs = draw(hnp.arrays(bool, m))
    contact = draw(hnp.arrays(bool, m))
    order = draw(st.lists(st.booleans(), max_size=n + m))
    return t, s, vt, vs, contact, order


@given(streams(), st.sampled_from([(5, 5, 1, 2), (20, 20, 5, 20), (3, 1, 0, 2)]))
@settings(max_examples=300)
def test_streamed_tracker_equals_detection_quality(data, windows_ms):
    t, s, vt, vs, contact, order = data
    lead, release, margin, gap = (w * MS for w in windows_ms)
    windows = dict(lead_ns=lead, release_ns=release, margin_ns=margin, min_gap_ns=gap)
    ref = detection_quality(t, s, vt, vs, in_contact=contact, **windows)
    tracker = _streamed(t, s, vt, vs, order, contact, **windows)
    assert tracker.quality() == ref
    assert (tracker.episode_count, tracker.detected, tracker.missed) == (len(ref.episodes), ref.detected, ref.missed)


def test_tracker_memory_stays_bounded_over_a_long_stream():
    """200 000 truth samples and verdicts with an episode every second: the tracker
    keeps a few hundred samples however long the stream (counts checked by hand)."""
    tracker = EpisodeTracker(max_kept=50)
    most = 0
    for k in range(200_000):
        stamp = k * MS
        gross = 500 <= k % 1000 < 520  # 20 ms of gross slip each second
        tracker.add_truth(stamp, gross)
        tracker.add_verdict(stamp, 495 <= k % 1000 < 525)  # flagged 5 ms early to 5 ms late
        most = max(most, len(tracker._truth) + len(tracker._pending) + len(tracker._open))
    tracker.finish()
    q = tracker.quality()
    assert tracker.episode_count == tracker.detected == 200 and tracker.missed == 0
    assert len(q.episodes) == len(q.delays_ns) == len(q.holds_ns) == 50
    assert set(q.delays_ns) == {-5 * MS} and set(q.holds_ns) == {6 * MS}
    assert q.false_alarm_frames == 0 and q.stick_frames == 200 * (1000 - 20)
    assert most < 300, most
