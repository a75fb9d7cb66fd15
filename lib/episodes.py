"""Slip episodes and detection quality: true slip (from the rig's truth) versus verdicts.

Used by the monitor's summary (streamed: :class:`EpisodeTracker`, bounded memory) and
by the detection-quality benchmark (whole recordings: :func:`detection_quality`). Times
are integer nanoseconds on one clock (the sensor sample stamps).

Definitions:
- an *episode* is a maximal run of samples with ``gross_slip`` true; onset = its first stamp;
- an episode is *detected* if a slip verdict occurs in ``[onset − lead, end + grace]``;
  the *delay* is the stamp of the verdict that raised the flag in that window minus the
  onset (negative: the detector warned before gross slip, which incipient-slip
  detection may do);
- an episode is *already flagged* if the first verdict of its window is a slip verdict:
  the flag was up before the window opened, so no delay is measured (it would only be
  the window's cut-off, −lead); it counts as detected, apart from the delays;
- a *flag without true slip* is a slip verdict on a frame whose nearest truth sample
  says stick and that lies in no episode's window; their share of the sticking frames is
  judged so. With the controller off these are false alarms; with it on they are mostly
  the early warnings it acts on (it grips harder, so the slip they announced never
  comes). Frames the truth marks *incipient* (partial slip: a large share of the
  contact's friction capacity, :data:`INCIPIENT_SHARE` as the callers use it, already
  sliding, not yet gross slip) are neither sticking nor slipping: a verdict there is an
  early warning and is not counted.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

__all__ = ["Episode", "DetectionQuality", "EpisodeTracker", "find_episodes", "detection_quality", "INCIPIENT_SHARE"]

LEAD_NS = 100_000_000
"""How early a verdict may come and still count for an episode (ns)."""
GRACE_NS = 50_000_000
"""How long after an episode's end a verdict still counts for it (ns)."""
MIN_GAP_NS = 20_000_000
"""Episodes closer than this are one episode (stick–slip chatter), ns."""

INCIPIENT_SHARE = 0.25
"""Partial slip counts as incipient when sliding taxels carry at least this share of the
contact's friction capacity (the rig's ``sliding_fraction``)."""


@dataclass(frozen=True)
class Episode:
    """One true gross-slip episode: ``[start_ns, end_ns]`` inclusive."""

    start_ns: int
    end_ns: int


@dataclass(frozen=True)
class DetectionQuality:
    """How verdicts match true episodes.

    delays_ns: one entry per episode whose flag rose in its window (verdict stamp − onset).
    already_flagged: episodes whose flag was up on the first verdict of their window
    (detected, no delay measured).
    missed: episodes with no slip verdict in their window.
    flag_without_slip_frames / stick_frames: slip verdicts on truly sticking frames outside
    every window / all frames judged while truly sticking.
    """

    episodes: tuple[Episode, ...]
    delays_ns: tuple[int, ...]
    already_flagged: int
    missed: int
    flag_without_slip_frames: int
    stick_frames: int

    @property
    def detected(self) -> int:
        return len(self.delays_ns) + self.already_flagged

    @property
    def flag_without_slip_share(self) -> float:
        """Flags without true slip over the frames judged while truly sticking (0 if none)."""
        return self.flag_without_slip_frames / self.stick_frames if self.stick_frames else 0.0

    def delay_percentile_ms(self, q: float) -> float:
        """``q``-th percentile of the detection delay in ms (NaN if nothing was detected)."""
        if not self.delays_ns:
            return float("nan")
        return float(np.percentile(np.asarray(self.delays_ns, dtype=float), q)) / 1e6


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
    grace_ns: int = GRACE_NS,
    min_gap_ns: int = MIN_GAP_NS,
    incipient: np.ndarray | None = None,
) -> DetectionQuality:
    """Match slip verdicts to true episodes (see the module docstring).

    Args:
        truth_ns, gross_slip: the rig's truth stream (stamps, flags).
        verdict_ns, verdict_slip: the detector's stream (sample stamps, slip flags).
        lead_ns: how early a verdict may come and still count for an episode.
        grace_ns: how long after an episode's end a verdict still counts for it.
        min_gap_ns: episodes closer than this are one episode (stick–slip chatter).
        incipient: optional flags on the truth stream: partial slip, excluded from the
            sticking frames.
    """
    episodes = find_episodes(truth_ns, gross_slip, min_gap_ns=min_gap_ns)
    vt = np.asarray(verdict_ns, dtype=np.int64)
    vs = np.asarray(verdict_slip, dtype=bool)
    in_window = np.zeros(vt.shape, dtype=bool)
    delays: list[int] = []
    missed = already_flagged = 0
    for ep in episodes:
        win = (vt >= ep.start_ns - lead_ns) & (vt <= ep.end_ns + grace_ns)
        in_window |= win
        hits = np.flatnonzero(win & vs)
        if not hits.size:
            missed += 1
        elif hits[0] == np.argmax(win):
            already_flagged += 1  # the window's first verdict: the flag rose before the window
        else:
            delays.append(int(vt[hits[0]] - ep.start_ns))
    stick = ~in_window
    if len(truth_ns):
        tt = np.asarray(truth_ns, dtype=np.int64)
        idx = np.clip(np.searchsorted(tt, vt), 0, tt.size - 1)
        stick &= ~np.asarray(gross_slip, dtype=bool)[idx]
        if incipient is not None:
            stick &= ~np.asarray(incipient, dtype=bool)[idx]
    return DetectionQuality(
        episodes=tuple(episodes), delays_ns=tuple(delays), already_flagged=already_flagged, missed=missed,
        flag_without_slip_frames=int(np.count_nonzero(stick & vs)), stick_frames=int(np.count_nonzero(stick)),
    )


_MAX_OPEN = 1000
"""Open episodes kept at most; beyond, the oldest is closed with the verdicts it has
(only when the detector's stream stalls for that many episodes)."""


class _OpenEpisode:
    """An episode whose window may still gain a verdict or whose end may still move."""

    __slots__ = ("start_ns", "end_ns", "ongoing", "delay_ns", "verdicts_seen", "already_flagged")

    def __init__(self, start_ns: int) -> None:
        self.start_ns = start_ns
        self.end_ns = start_ns
        self.ongoing = True
        self.delay_ns: int | None = None
        self.verdicts_seen = False
        self.already_flagged = False


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
    1000), and the latest ``max_kept`` finished episodes and delays (the counts
    ``episode_count``, ``detected``, ``already_flagged``, ``missed`` cover all of them).
    """

    def __init__(self, *, lead_ns: int = LEAD_NS, grace_ns: int = GRACE_NS, min_gap_ns: int = MIN_GAP_NS,
                 horizon_ns: int = 10_000_000_000, max_pending: int = 100_000, max_kept: int = 10_000) -> None:
        self.lead_ns, self.grace_ns, self.min_gap_ns, self.horizon_ns = lead_ns, grace_ns, min_gap_ns, horizon_ns
        self.max_pending = max_pending
        self._truth: deque[tuple[int, bool, bool]] = deque()  # (stamp, gross slip, incipient)
        self._truth_end: int | None = None
        self._in_slip = False
        self._open: deque[_OpenEpisode] = deque()
        self._pending: deque[tuple[int, bool]] = deque()
        self._last_judged_ns: int | None = None
        self.finished: deque[Episode] = deque(maxlen=max_kept)
        self.delays_ns: deque[int] = deque(maxlen=max_kept)
        self.episode_count = 0
        self.detected = 0
        self.already_flagged = 0
        self.missed = 0
        self.stick_frames = 0
        self.flag_without_slip_frames = 0

    def add_truth(self, stamp_ns: int, gross_slip: bool, incipient: bool = False) -> None:
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
        self._truth.append((stamp_ns, gross_slip, incipient))
        self._truth_end = stamp_ns
        while self._truth[0][0] < stamp_ns - self.horizon_ns:
            self._truth.popleft()
        self._judge_ready()

    def add_verdict(self, stamp_ns: int, slip: bool) -> None:
        """One verdict of the detector (stamps increasing)."""
        self._pending.append((stamp_ns, slip))
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
        """The numbers so far (the kept episodes and delays: the latest ``max_kept``)."""
        return DetectionQuality(episodes=tuple(self.finished), delays_ns=tuple(self.delays_ns),
                                already_flagged=self.already_flagged, missed=self.missed,
                                flag_without_slip_frames=self.flag_without_slip_frames, stick_frames=self.stick_frames)

    def _judge_ready(self) -> None:
        pending = self._pending
        while pending and self._truth_end is not None and self._truth_end >= pending[0][0] + self.lead_ns:
            self._judge(*pending.popleft())
        self._close_episodes(final=False)

    def _judge(self, t: int, slip: bool) -> None:
        in_window = False
        for ep in self._open:
            if ep.start_ns - self.lead_ns <= t and (ep.ongoing or t <= ep.end_ns + self.grace_ns):
                in_window = True
                if not ep.verdicts_seen:
                    ep.verdicts_seen = True
                    ep.already_flagged = slip  # up on the window's first verdict: raised before it
                elif slip and ep.delay_ns is None and not ep.already_flagged:
                    ep.delay_ns = t - ep.start_ns
        truth = self._truth
        while len(truth) > 1 and truth[0][0] < t:
            truth.popleft()  # the first sample at or after t is the one that judges it
        if not in_window:
            sticking = not truth or not (truth[0][1] or truth[0][2])
            if sticking:
                self.stick_frames += 1
                self.flag_without_slip_frames += slip
        self._last_judged_ns = t if self._last_judged_ns is None else max(self._last_judged_ns, t)

    def _close_episodes(self, *, final: bool) -> None:
        while self._open:
            ep = self._open[0]
            if not final and len(self._open) <= _MAX_OPEN:
                if ep.ongoing or self._truth_end is None or self._truth_end < ep.end_ns + self.min_gap_ns:
                    return  # it may still go on or merge with the next run
                if self._last_judged_ns is None or self._last_judged_ns <= ep.end_ns + self.grace_ns:
                    return  # a verdict in its window may still come
            self._open.popleft()
            self.episode_count += 1
            self.finished.append(Episode(ep.start_ns, ep.end_ns))
            if ep.already_flagged:
                self.detected += 1
                self.already_flagged += 1
            elif ep.delay_ns is None:
                self.missed += 1
            else:
                self.detected += 1
                self.delays_ns.append(ep.delay_ns)
