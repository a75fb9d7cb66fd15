"""Slip episodes and detection quality: true slip (from the rig's truth) versus verdicts.

Used by the default run's summary and by the detection-quality benchmark. Times are
integer nanoseconds on one clock (the sensor sample stamps).

Definitions:
- an *episode* is a maximal run of samples with ``gross_slip`` true; onset = its first stamp;
- an episode is *detected* if a slip verdict occurs in ``[onset − lead, end + grace]``;
  the *delay* is the first such verdict's stamp minus the onset (negative: the detector
  warned before gross slip, which incipient-slip detection may do);
- a *false slip* is a slip verdict on a frame whose nearest truth sample says stick and
  that lies in no episode's window. Frames the truth marks *incipient* (partial slip:
  most of the contact's friction capacity already sliding, not yet gross slip) are
  neither sticking nor slipping: a verdict there is an early warning, not an error.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Episode", "DetectionQuality", "find_episodes", "detection_quality", "INCIPIENT_SHARE"]

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

    delays_ns: one entry per detected episode (verdict stamp − onset).
    missed: episodes with no verdict in their window.
    false_slip_frames / stick_frames: verdict frames outside every window / all frames
    judged while truly sticking.
    """

    episodes: tuple[Episode, ...]
    delays_ns: tuple[int, ...]
    missed: int
    false_slip_frames: int
    stick_frames: int

    @property
    def detected(self) -> int:
        return len(self.delays_ns)

    @property
    def false_slip_rate(self) -> float:
        return self.false_slip_frames / self.stick_frames if self.stick_frames else 0.0

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
    lead_ns: int = 100_000_000,
    grace_ns: int = 50_000_000,
    min_gap_ns: int = 20_000_000,
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
    missed = 0
    for ep in episodes:
        win = (vt >= ep.start_ns - lead_ns) & (vt <= ep.end_ns + grace_ns)
        in_window |= win
        hits = np.flatnonzero(win & vs)
        if hits.size:
            delays.append(int(vt[hits[0]] - ep.start_ns))
        else:
            missed += 1
    stick = ~in_window
    if len(truth_ns):
        tt = np.asarray(truth_ns, dtype=np.int64)
        idx = np.clip(np.searchsorted(tt, vt), 0, tt.size - 1)
        stick &= ~np.asarray(gross_slip, dtype=bool)[idx]
        if incipient is not None:
            stick &= ~np.asarray(incipient, dtype=bool)[idx]
    return DetectionQuality(
        episodes=tuple(episodes), delays_ns=tuple(delays), missed=missed,
        false_slip_frames=int(np.count_nonzero(stick & vs)), stick_frames=int(np.count_nonzero(stick)),
    )
