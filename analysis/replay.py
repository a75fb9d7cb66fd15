"""A run's contacts replayed through the slip detector, and its flags scored against the truth.

:func:`replay_gammas` steps a ``slip_detector`` node's own :class:`~slipstack.lib.detector.Detector`
over a run's ``contact`` messages with another test, and keeps each frame's load factor γ
and validity; :func:`latch_flags` runs the detector's latch over them with any band δ
(and, since every test's γ is inversely proportional to μ, any error of μ) without
stepping the test again. :func:`score_flags` scores flags by the one detection definition
(``lib/episodes.py``, docs/math.md §3.2); the sensitivity and the report's first section use both.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass

import numpy as np

from slipstack.lib.detection import DetectorConfig, SlipLatch
from slipstack.lib.detector import ONSET_NS_PER_FRAME
from slipstack.lib.episodes import LEAD_NS, MARGIN_NS, DetectionQuality, detection_quality
from slipstack.lib.status import SlipState
from slipstack.nodes.slip_detector import SlipDetector

__all__ = ["FrameGammas", "Quality", "replay_gammas", "gammas", "latch_config", "latch_flags", "score_flags",
           "LEAD_NS", "MARGIN_NS", "NO_EPISODES"]


@dataclass(frozen=True)
class FrameGammas:
    """One replay: per contact frame its stamp (ns), γ of the test (NaN without a valid
    verdict), whether the detector saw contact, and the mean cost of a step (µs)."""

    method: str
    t_ns: np.ndarray
    gamma: np.ndarray
    in_contact: np.ndarray
    us_per_frame: float


def replay_gammas(run, method: str, *, pool: int = 1, beta_m: float | None = None) -> FrameGammas:
    """Step a fresh detector with ``method`` (``pool``, ``beta_m``: else the run's) over the
    run's contacts, timed; the run's other detector parameters."""
    changes = {"method": method, "pool": pool, "also": []}
    if beta_m is not None:
        changes["beta_m"] = beta_m
    if method != "tactile_cor_known":
        changes.update(known_cor_x_m=math.nan, known_cor_y_m=math.nan)
    detector = SlipDetector(dataclasses.replace(run.detector, **changes)).detector
    n = len(run.contacts)
    t_ns, gamma, in_contact = np.empty(n, dtype=np.int64), np.full(n, math.nan), np.empty(n, dtype=bool)
    elapsed = 0
    for i, msg in enumerate(run.contacts):
        start = time.perf_counter_ns()
        v = detector.step(msg, msg.header.stamp_ns, tactile_frame=msg.header.sources.get("tactile"))
        elapsed += time.perf_counter_ns() - start
        t_ns[i] = msg.header.stamp_ns
        in_contact[i] = v.state != SlipState.NO_CONTACT
        if v.status == "ok":
            gamma[i] = v.gamma
    return FrameGammas(method, t_ns, gamma, in_contact, elapsed / 1e3 / max(n, 1))


def gammas(run, method: str) -> FrameGammas:
    """``method``'s load factors on the run: the published ``slip`` verdicts where the run's
    detector decided with it (untimed: cost NaN), else a replay, made once per run."""
    p = run.detector
    if method != p.method or p.pool != 1:
        if method not in run.replays:
            run.replays[method] = replay_gammas(run, method)
        return run.replays[method]
    s = run["slip"]
    ok = s["status"] == "ok"
    return FrameGammas(method, np.round(s["t"] * 1e9).astype(np.int64), np.where(ok, s["gamma"], math.nan).astype(float),
                       s["state"] != SlipState.NO_CONTACT, math.nan)


def latch_config(run, delta: float | None = None) -> DetectorConfig:
    """The latch the run's detector ran (its material's thresholds), with band ``delta`` if given."""
    p = run.detector
    return DetectorConfig(p.delta if delta is None else delta, p.gamma_release, round(p.release_ms * 1e6),
                          p.gamma_resume, p.onset_frames, (p.onset_frames - 1) * ONSET_NS_PER_FRAME)


def latch_flags(frames: FrameGammas, config: DetectorConfig, *, mu_error: float = 0.0) -> np.ndarray:
    """The latched flag per frame for ``config``, with the test run at μ·(1 + ``mu_error``):
    every test's γ is proportional to 1/μ (docs/math.md §3, §4.1)."""
    latch = SlipLatch(config)
    margin = 1.0 - frames.gamma / (1.0 + mu_error)
    return np.array([latch.update(t, m, in_contact=c) for t, m, c in
                     zip(frames.t_ns.tolist(), margin.tolist(), frames.in_contact.tolist())], dtype=bool)


@dataclass(frozen=True)
class Quality:
    """:class:`~slipstack.lib.episodes.DetectionQuality` summed over runs: episodes (a count),
    missed, delays_ns (flag rise − onset per detected episode; negative: a warning),
    false_alarm_frames, latch_hold_frames (those of them on a flag that rose for an episode)
    and stick_frames, as ``lib/episodes.py`` defines them (docs/math.md §3.2)."""

    episodes: int
    missed: int
    delays_ns: tuple[int, ...]
    false_alarm_frames: int
    latch_hold_frames: int
    stick_frames: int

    @classmethod
    def of(cls, q: DetectionQuality) -> Quality:
        return cls(len(q.episodes), q.missed, q.delays_ns, q.false_alarm_frames, q.latch_hold_frames, q.stick_frames)

    @property
    def false_alarm_share(self) -> float:
        return self.false_alarm_frames / self.stick_frames if self.stick_frames else 0.0

    @property
    def latch_hold_share(self) -> float:
        return self.latch_hold_frames / self.stick_frames if self.stick_frames else 0.0

    def __add__(self, other: Quality) -> Quality:
        return Quality(self.episodes + other.episodes, self.missed + other.missed, self.delays_ns + other.delays_ns,
                       self.false_alarm_frames + other.false_alarm_frames,
                       self.latch_hold_frames + other.latch_hold_frames, self.stick_frames + other.stick_frames)


NO_EPISODES = Quality(0, 0, (), 0, 0, 0)


def score_flags(truth_ns: np.ndarray, gross_slip: np.ndarray, t_ns: np.ndarray, flags: np.ndarray,
                in_contact: np.ndarray, release_ns: int) -> Quality:
    """Score ``flags`` (one per frame stamped ``t_ns``) against the truth's gross slip with the
    latch's release dwell ``release_ns`` (:func:`slipstack.lib.episodes.detection_quality`)."""
    return Quality.of(detection_quality(truth_ns, gross_slip, t_ns, flags, release_ns=release_ns,
                                        in_contact=in_contact))
