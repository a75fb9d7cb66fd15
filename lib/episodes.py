"""Slip episodes and detection quality: true slip (from the rig's truth) versus verdicts.

One definition (docs/math.md §3.2), used by the monitor's summary (streamed:
:class:`EpisodeTracker`, bounded memory), the detection benchmark and the figures
(whole recordings: :func:`detection_quality`): an *episode* is a stretch of true gross
slip; *missed*: no flag from ``lead`` before its onset to its end; *delay*: rise of that
flag minus the onset (negative: a warning); *false alarms*: sticking frames flagged
outside every episode's window ``[onset − lead, end + release + margin]``, over all
sticking frames, the *latch hold* (a flag that rose for an episode and stays up after
it) counted apart among them. Times are integer ns on one clock.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

__all__ = ["Episode", "DetectionQuality", "EpisodeTracker", "find_episodes", "detection_quality",
           "LEAD_NS", "RELEASE_NS", "MARGIN_NS", "MIN_GAP_NS"]

LEAD_NS = 20_000_000
"""How early a flag may rise and still count for an episode (ns)."""
RELEASE_NS = 20_000_000
"""The latch's release dwell (``lib/detection.py``'s default), ns: the window after an episode."""
MARGIN_NS = 5_000_000
"""Beyond the release dwell, how long after an episode a flag is still its latch (ns)."""
MIN_GAP_NS = 20_000_000
"""Episodes closer than this are one episode (stick–slip chatter), ns."""


@dataclass(frozen=True)
class Episode:
    """One true gross-slip episode: ``[start_ns, end_ns]`` inclusive."""

    start_ns: int
    end_ns: int


@dataclass(frozen=True)
class DetectionQuality:
    """How verdicts match true episodes.

    delays_ns: per detected episode, the rise of its flag minus its onset.
    holds_ns: per detected episode, how long the flag stayed up after its end (0: down by then).
    missed: episodes with no flag from ``lead`` before their onset to their end.
    false_alarm_frames / stick_frames: flagged sticking frames outside every episode's
    window / all sticking frames; latch_hold_frames: those of them whose flag was up inside
    an episode's window before (the latch holding on after the slip).
    """

    episodes: tuple[Episode, ...]
    delays_ns: tuple[int, ...]
    holds_ns: tuple[int, ...]
    missed: int
    false_alarm_frames: int
    latch_hold_frames: int
    stick_frames: int

    @property
    def detected(self) -> int:
        return len(self.delays_ns)

    @property
    def false_alarm_share(self) -> float:
        """False-alarm frames over all sticking frames (0 without any)."""
        return self.false_alarm_frames / self.stick_frames if self.stick_frames else 0.0

    @property
    def latch_hold_share(self) -> float:
        """The latch-hold part of :attr:`false_alarm_share`."""
        return self.latch_hold_frames / self.stick_frames if self.stick_frames else 0.0

    def delay_percentile_ms(self, q: float) -> float:
        """``q``-th percentile of the detection delay in ms (NaN if nothing was detected)."""
        return _percentile_ms(self.delays_ns, q)

    def hold_percentile_ms(self, q: float) -> float:
        """``q``-th percentile of the latch hold after an episode in ms (NaN if none detected)."""
        return _percentile_ms(self.holds_ns, q)


def _percentile_ms(values: tuple[int, ...], q: float) -> float:
    return float(np.percentile(np.asarray(values, dtype=float), q)) / 1e6 if values else float("nan")


def find_episodes(stamps_ns: np.ndarray, gross_slip: np.ndarray, *, min_gap_ns: int = 0) -> list[Episode]:
    """Maximal runs of ``gross_slip``; runs separated by less than ``min_gap_ns`` are merged."""
    t = np.asarray(stamps_ns, dtype=np.int64)
    s = np.asarray(gross_slip, dtype=bool)
    episodes: list[Episode] = []
    if t.size == 0:
        return episodes
    edges = np.flatnonzero(np.diff(np.concatenate([[False], s, [False]]).astype(np.int8)))
    for a, b in zip(edges[::2], edges[1::2]):
        ep = Episode(int(t[a]), int(t[b - 1]))
        if episodes and ep.start_ns - episodes[-1].end_ns < min_gap_ns:
            episodes[-1] = Episode(episodes[-1].start_ns, ep.end_ns)
        else:
            episodes.append(ep)
    return episodes


def detection_quality(
    truth_ns: np.ndarray,
    gross_slip: np.ndarray,
    verdict_ns: np.ndarray,
    verdict_slip: np.ndarray,
    *,
    lead_ns: int = LEAD_NS,
    release_ns: int = RELEASE_NS,
    margin_ns: int = MARGIN_NS,
    min_gap_ns: int = MIN_GAP_NS,
    in_contact: np.ndarray | None = None,
) -> DetectionQuality:
    """Match slip verdicts to true episodes (module docstring).

    Args:
        truth_ns, gross_slip: the truth stream (stamps, flags); a verdict is judged by the
            first truth sample at or after its stamp.
        verdict_ns, verdict_slip: the detector's stream (sample stamps, slip flags).
        lead_ns, release_ns, margin_ns, min_gap_ns: the windows (module constants).
        in_contact: optional per-verdict flags; frames without contact are not sticking frames.
    """
    episodes = find_episodes(truth_ns, gross_slip, min_gap_ns=min_gap_ns)
    vt = np.asarray(verdict_ns, dtype=np.int64)
    vs = np.asarray(verdict_slip, dtype=bool)
    n = vt.size
    index = np.arange(n)
    run_start = np.maximum.accumulate(np.where(vs & ~np.concatenate([[False], vs[:-1]]), index, 0)) if n else index
    excused = np.zeros(n, dtype=bool)
    detecting = np.zeros(n, dtype=bool)
    delays: list[int] = []
    holds: list[int] = []
    missed = 0
    for ep in episodes:
        window = (vt >= ep.start_ns - lead_ns) & (vt <= ep.end_ns)
        excused |= (vt >= ep.start_ns - lead_ns) & (vt <= ep.end_ns + release_ns + margin_ns)
        detecting |= window
        hits = np.flatnonzero(window & vs)
        if not hits.size:
            missed += 1
            continue
        delays.append(int(vt[run_start[hits[0]]] - ep.start_ns))
        holds.append(_hold_ns(vt, vs, ep.end_ns))
    sticking = np.ones(n, dtype=bool)
    if len(truth_ns):
        tt = np.asarray(truth_ns, dtype=np.int64)
        sticking &= ~np.asarray(gross_slip, dtype=bool)[np.clip(np.searchsorted(tt, vt), 0, tt.size - 1)]
    if in_contact is not None:
        sticking &= np.asarray(in_contact, dtype=bool)
    seen = np.cumsum(vs & detecting)  # flagged frames inside a window, so far
    before_run = np.where(run_start > 0, seen[np.maximum(run_start - 1, 0)], 0)
    latch = (seen - before_run) > 0  # this flag run had a frame in a window, at or before this one
    false = vs & sticking & ~excused
    return DetectionQuality(episodes=tuple(episodes), delays_ns=tuple(delays), holds_ns=tuple(holds),
                            missed=missed, false_alarm_frames=int(np.count_nonzero(false)),
                            latch_hold_frames=int(np.count_nonzero(false & latch)),
                            stick_frames=int(np.count_nonzero(sticking)))


def _hold_ns(vt: np.ndarray, vs: np.ndarray, end_ns: int) -> int:
    """How long after ``end_ns`` the flag stays up: the first unflagged verdict after it,
    or the last verdict if it never falls; 0 if the last verdict up to ``end_ns`` is down."""
    last = int(np.searchsorted(vt, end_ns, side="right")) - 1
    if last < 0 or not vs[last]:
        return 0
    down = np.flatnonzero(~vs[last + 1:])
    fall = vt[last + 1 + down[0]] if down.size else vt[-1]
    return max(int(fall - end_ns), 0)


_MAX_OPEN = 1000
"""Open episodes kept at most; beyond, the oldest is closed with the verdicts it has
(only when the detector's stream stalls for that many episodes)."""


class _OpenEpisode:
    """An episode whose windows may still gain a verdict or whose end may still move."""

    __slots__ = ("start_ns", "end_ns", "ongoing", "delay_ns", "hold_ns", "up_at_end")

    def __init__(self, start_ns: int) -> None:
        self.start_ns = start_ns
        self.end_ns = start_ns
        self.ongoing = True
        self.delay_ns: int | None = None
        self.hold_ns: int | None = None
        self.up_at_end = False  # the flag of the newest verdict up to the end


class EpisodeTracker:
    """:func:`detection_quality` computed on the fly, in bounded memory.

    Feed the truth stream with :meth:`add_truth` and the verdicts with
    :meth:`add_verdict`, interleaved as they arrive (each stream in stamp order); call
    :meth:`finish` at the end, then :meth:`quality`. The result equals
    :func:`detection_quality` over the same streams (same definitions, same defaults)
    as long as no verdict lags the truth by more than ``horizon_ns``.

    What is kept: verdicts not yet judged (they wait until the truth has reached
    their stamp + ``lead_ns``; at most ``max_pending``, beyond which the oldest is
    judged on the truth seen so far), truth samples from the oldest pending verdict on
    (at most ``horizon_ns`` of them), the episodes whose window is still open (at most
    1000), and the latest ``max_kept`` finished episodes, delays and holds (the counts
    ``episode_count``, ``detected``, ``missed`` cover all of them).
    """

    def __init__(self, *, lead_ns: int = LEAD_NS, release_ns: int = RELEASE_NS, margin_ns: int = MARGIN_NS,
                 min_gap_ns: int = MIN_GAP_NS, horizon_ns: int = 10_000_000_000, max_pending: int = 100_000,
                 max_kept: int = 10_000) -> None:
        self.lead_ns, self.min_gap_ns, self.horizon_ns = lead_ns, min_gap_ns, horizon_ns
        self.after_ns = release_ns + margin_ns
        self.max_pending = max_pending
        self._truth: deque[tuple[int, bool]] = deque()  # (stamp, gross slip)
        self._truth_end: int | None = None
        self._in_slip = False
        self._open: deque[_OpenEpisode] = deque()
        self._pending: deque[tuple[int, bool, bool]] = deque()  # (stamp, slip, in contact)
        self._last_judged_ns: int | None = None
        self._flag_up = False
        self._rise_ns = 0  # stamp of the newest flag rise
        self._run_detected = False  # the current flag run had a frame inside an episode's window
        self.finished: deque[Episode] = deque(maxlen=max_kept)
        self.delays_ns: deque[int] = deque(maxlen=max_kept)
        self.holds_ns: deque[int] = deque(maxlen=max_kept)
        self.episode_count = 0
        self.detected = 0
        self.missed = 0
        self.stick_frames = 0
        self.false_alarm_frames = 0
        self.latch_hold_frames = 0

    def add_truth(self, stamp_ns: int, gross_slip: bool) -> None:
        """One truth sample (stamps increasing)."""
        if gross_slip:
            last = self._open[-1] if self._open else None
            if not self._in_slip:
                if last is not None and stamp_ns - last.end_ns < self.min_gap_ns:
                    last.ongoing = True  # chatter: the same episode goes on
                else:
                    self._open.append(_OpenEpisode(stamp_ns))
            self._open[-1].end_ns = stamp_ns
        elif self._in_slip:
            self._open[-1].ongoing = False
        self._in_slip = gross_slip
        self._truth.append((stamp_ns, gross_slip))
        self._truth_end = stamp_ns
        while self._truth[0][0] < stamp_ns - self.horizon_ns:
            self._truth.popleft()
        self._judge_ready()

    def add_verdict(self, stamp_ns: int, slip: bool, in_contact: bool = True) -> None:
        """One verdict of the detector (stamps increasing)."""
        self._pending.append((stamp_ns, slip, in_contact))
        while len(self._pending) > self.max_pending:
            self._judge(*self._pending.popleft())
        self._judge_ready()

    def finish(self) -> None:
        """The streams ended: judge every pending verdict and close every episode."""
        for ep in self._open:
            ep.ongoing = False  # the truth is complete: a run still going ends at its last sample
        self._in_slip = False
        while self._pending:
            self._judge(*self._pending.popleft())
        self._close_episodes(final=True)

    def quality(self) -> DetectionQuality:
        """The numbers so far (the kept episodes, delays and holds: the latest ``max_kept``)."""
        return DetectionQuality(episodes=tuple(self.finished), delays_ns=tuple(self.delays_ns),
                                holds_ns=tuple(self.holds_ns), missed=self.missed,
                                false_alarm_frames=self.false_alarm_frames,
                                latch_hold_frames=self.latch_hold_frames, stick_frames=self.stick_frames)

    def _judge_ready(self) -> None:
        pending = self._pending
        while pending and self._truth_end is not None and self._truth_end >= pending[0][0] + self.lead_ns:
            self._judge(*pending.popleft())
        self._close_episodes(final=False)

    def _judge(self, t: int, slip: bool, in_contact: bool) -> None:
        if slip and not self._flag_up:
            self._rise_ns, self._run_detected = t, False
        self._flag_up = slip
        excused = False
        for ep in self._open:
            if t < ep.start_ns - self.lead_ns:
                continue
            if ep.ongoing or t <= ep.end_ns:
                if slip:
                    self._run_detected = True
                    if ep.delay_ns is None:
                        ep.delay_ns = self._rise_ns - ep.start_ns
                ep.up_at_end = slip
                excused = True
            else:
                if ep.hold_ns is None and ep.delay_ns is not None:
                    ep.hold_ns = t - ep.end_ns if ep.up_at_end and not slip else 0 if not ep.up_at_end else None
                excused |= t <= ep.end_ns + self.after_ns
        truth = self._truth
        while len(truth) > 1 and truth[0][0] < t:
            truth.popleft()  # the first sample at or after t is the one that judges it
        if in_contact and not (truth and truth[0][1]):
            self.stick_frames += 1
            if slip and not excused:
                self.false_alarm_frames += 1
                self.latch_hold_frames += self._run_detected
        self._last_judged_ns = t if self._last_judged_ns is None else max(self._last_judged_ns, t)

    def _close_episodes(self, *, final: bool) -> None:
        while self._open:
            ep = self._open[0]
            if not final and len(self._open) <= _MAX_OPEN:
                if ep.ongoing or self._truth_end is None or self._truth_end < ep.end_ns + self.min_gap_ns:
                    return  # it may still go on or merge with the next run
                if self._last_judged_ns is None or self._last_judged_ns <= ep.end_ns + self.after_ns:
                    return  # a verdict in its window may still come
                if ep.delay_ns is not None and ep.hold_ns is None:
                    return  # its flag is still up: the hold goes on
            self._open.popleft()
            self.episode_count += 1
            self.finished.append(Episode(ep.start_ns, ep.end_ns))
            if ep.delay_ns is None:
                self.missed += 1
            else:
                self.detected += 1
                self.delays_ns.append(ep.delay_ns)
                if ep.hold_ns is None:  # never fell: up to the last verdict
                    ep.hold_ns = max((self._last_judged_ns or 0) - ep.end_ns, 0) if ep.up_at_end else 0
                self.holds_ns.append(ep.hold_ns)
