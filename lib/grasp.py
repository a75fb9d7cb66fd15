"""Two fingers, one squeeze: the least holding squeeze, the pads' view of the object, pivot and slide.

docs/math.md §9. Each finger's loads are in its own pad frame; finger 1's frame is finger
0's turned by 180° about ``y`` (a planar point ``(x, y)`` of finger 0's frame ``F`` is
``(−x, y)`` in it, a torque about ``z`` changes sign), and the object's motion is told
in ``F``. Pure computation: times are integer ns passed in, nothing raises on bad data.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from slipstack.lib.grip_laws import GripInput, GripLaw
from slipstack.lib.limit_set import load_factor
from slipstack.lib.status import SolverStatus

__all__ = [
    "SqueezeLaw", "least_squeeze", "load_shares", "to_finger0", "combined_contact", "TurnPrediction", "predict_turn",
    "PadPose", "pad_pose", "ObjectMotion", "MotionEstimator", "ModeOutput", "TrackGains", "PIVOT_GAINS",
    "SLIDE_GAINS", "BREAKAWAY_SHARE", "TrackControl", "TextureOdometer",
]


@dataclass(frozen=True, kw_only=True)
class SqueezeLaw(GripLaw):
    """The grasp node's squeeze as a grip law: the demand it computed (``GripInput.demand_n``,
    N), so :class:`~slipstack.lib.grip_laws.GripGovernor` bounds it, limits its rate and holds
    it on data it cannot trust, exactly as for one finger."""

    name: ClassVar[str] = "squeeze"
    needs: ClassVar[tuple[str, ...]] = ("demand_n",)

    def demand(self, inp: GripInput, dt_s: float) -> float:
        return inp.demand_n


def least_squeeze(gammas: tuple[float, float], f_ns: tuple[float, float]) -> float:
    """``max_i γ_i f_n,i`` (N): the least squeeze with which both contacts hold their measured
    loads (the load factor γ scales as ``1/f_n`` for a pressure shape that scales with the
    force); NaN if either is NaN (no verdict), ``inf`` if either load cannot be held."""
    out = 0.0
    for gamma, f_n in zip(gammas, f_ns):
        value = gamma * f_n
        if value != value:
            return math.nan
        out = max(out, value)
    return out


def load_shares(f_t: tuple[tuple[float, float], tuple[float, float]]) -> tuple[float, float]:
    """Each finger's share of the tangential load, ``|f_t,i| / Σ |f_t,j|`` (0.5 each with none)."""
    a, b = math.hypot(*f_t[0]), math.hypot(*f_t[1])
    total = a + b
    return (0.5, 0.5) if total <= 0.0 else (a / total, b / total)


def to_finger0(f_t: tuple[float, float], tau: float) -> tuple[tuple[float, float], float]:
    """Finger 1's load (its frame) in finger 0's frame: ``(f_x, f_y, τ) → (−f_x, f_y, −τ)``."""
    return (-f_t[0], f_t[1]), -tau


def combined_contact(phi: tuple[np.ndarray, np.ndarray], positions: np.ndarray,
                     loads: tuple[tuple[tuple[float, float], float], tuple[tuple[float, float], float]]
                     ) -> tuple[np.ndarray, np.ndarray, tuple[float, float], float]:
    """Both pads as one contact in ``F``: ``(φ (2N,), positions (2N, 2), f_t, τ)``.

    The object is rigid and both pads are fixed to the gripper, so it moves relative to
    both with one twist: the two contacts resist it as one, whose limit set is the sum of
    theirs (docs/math.md §9). ``phi`` per pad (N each), ``positions`` (N, 2) the pad's
    taxels in its own frame; ``loads`` per finger ``(f_t, τ)`` in its own frame.
    """
    mirrored = positions * np.array([-1.0, 1.0])
    (f0, tau0), (f1, tau1) = loads[0], to_finger0(*loads[1])
    return (np.concatenate(phi), np.concatenate([positions, mirrored]),
            (f0[0] + f1[0], f0[1] + f1[1]), tau0 + tau1)


@dataclass(frozen=True)
class TurnPrediction:
    """What the exact limit set of both pads predicts for the measured load (docs/math.md §9).

    start_n: the squeeze below which the object starts to move (static friction, N);
    kinetic_n: the squeeze at which sliding friction balances the load (N): between the
    two the object keeps moving once it moves; hold_translation_n: the least squeeze that
    holds the load's force alone with sliding friction (N), the floor a pivot never goes
    below; sense: +1 the load turns the object counter-clockwise in ``F``, −1 clockwise,
    0 no turn (a translation); cor: the centre of rotation of impending slip in ``F`` (m),
    None for a translation. usable: the solver answered.
    """

    start_n: float
    kinetic_n: float
    hold_translation_n: float
    sense: int
    cor: tuple[float, float] | None
    usable: bool


def predict_turn(phi: np.ndarray, positions: np.ndarray, f_t: tuple[float, float], tau: float, squeeze_n: float,
                 mu_s: float, mu_d: float) -> TurnPrediction:
    """:class:`TurnPrediction` for the combined contact (:func:`combined_contact`) pressed with
    ``squeeze_n`` (each pad's normal force, N), friction ``mu_s``/``mu_d``."""
    static = load_factor(phi, positions, f_t, tau, mu_s)
    if not static.status.usable or static.status is SolverStatus.NO_CONTACT:
        return TurnPrediction(math.nan, math.nan, math.nan, 0, None, False)
    force = math.hypot(*f_t)
    return TurnPrediction(static.gamma * squeeze_n, static.gamma * squeeze_n * mu_s / mu_d,
                          force / (2.0 * mu_d), static.sense, static.p_c, True)


@dataclass(frozen=True)
class PadPose:
    """Where a pad's pressure lies: its centroid (m, the pad's frame), the angle of its
    principal axis (rad, mod π) and how elongated it is (the axes' variance ratio ≥ 1;
    an angle is told only when it is clearly above 1)."""

    centroid: tuple[float, float]
    angle: float
    elongation: float
    force: float


def pad_pose(phi: np.ndarray, positions: np.ndarray) -> PadPose | None:
    """:class:`PadPose` of one pad's normal forces ``phi`` (N per taxel); None without contact."""
    total = float(phi.sum())
    if not total > 0.0:
        return None
    w = phi / total
    cx, cy = float(w @ positions[:, 0]), float(w @ positions[:, 1])
    dx, dy = positions[:, 0] - cx, positions[:, 1] - cy
    m20, m02, m11 = float(w @ (dx * dx)), float(w @ (dy * dy)), float(w @ (dx * dy))
    half_diff = math.hypot(0.5 * (m20 - m02), m11)
    mean = 0.5 * (m20 + m02)
    minor = mean - half_diff
    elongation = (mean + half_diff) / minor if minor > 0.0 else math.inf
    return PadPose((cx, cy), 0.5 * math.atan2(2.0 * m11, m20 - m02), elongation, total)


def _wrap_half_turn(a: float) -> float:
    """``a`` wrapped to (−π/2, π/2]: an axis has no sense."""
    return a - math.pi * math.floor(a / math.pi + 0.5)


@dataclass(frozen=True)
class ObjectMotion:
    """The object's motion since the reference, as both pads see it, in ``F``.

    angle: turned (rad, counter-clockwise positive); rate: its rate (rad/s);
    shift: the translation of the object point that was on the grasp axis (m, (x, y));
    speed: how fast that point moves (m/s);
    sees_angle: both pads see an elongated footprint (otherwise ``angle`` is 0).
    """

    angle: float
    rate: float
    shift: tuple[float, float]
    speed: float
    sees_angle: bool


class MotionEstimator:
    """Tracks the object's angle and translation from the two pads' pressure frames.

    Each pad's footprint moves with the object's slip (a rubber patch stuck to the object
    moves with it): its principal axis turns with the object (finger 1's the other way) and
    its centroid moves with it. The angle is unwrapped frame to frame (an axis is known mod
    π), both pads averaged; the rate is the slope of a least-squares line through the angles
    of the last ``window_ns``. ``min_elongation``: a footprint rounder than this shows no
    angle (a disc, a whole pad).
    """

    def __init__(self, window_ns: int = 30_000_000, min_elongation: float = 1.3, max_frames: int = 64) -> None:
        self.window_ns = window_ns
        self.min_elongation = min_elongation
        self._history: deque[tuple[int, float]] = deque(maxlen=max_frames)
        self._shifts: tuple[deque[tuple[int, float]], deque[tuple[int, float]]] = (
            deque(maxlen=max_frames), deque(maxlen=max_frames))
        self._ref: tuple[PadPose, PadPose] | None = None
        self._last_angles = (0.0, 0.0)
        self._unwrapped = (0.0, 0.0)
        self.motion = ObjectMotion(0.0, 0.0, (0.0, 0.0), 0.0, False)

    def reset(self) -> None:
        """Forget the reference: the next frames start a new one."""
        self._ref = None
        self._history.clear()
        for h in self._shifts:
            h.clear()
        self.motion = ObjectMotion(0.0, 0.0, (0.0, 0.0), 0.0, False)

    def update(self, t_ns: int, poses: tuple[PadPose, PadPose]) -> ObjectMotion:
        """Take both pads' poses at ``t_ns`` (finger 1's in its own frame); the motion now."""
        p0, p1 = poses
        if self._ref is None:
            self._ref = poses
            self._last_angles = (p0.angle, p1.angle)
            self._unwrapped = (0.0, 0.0)
        sees = min(p0.elongation, p1.elongation) >= self.min_elongation
        turned = []
        for k, pose in enumerate(poses):
            step = _wrap_half_turn(pose.angle - self._last_angles[k])
            turned.append(self._unwrapped[k] + step)
        self._last_angles = (p0.angle, p1.angle)
        self._unwrapped = (turned[0], turned[1])
        angle = 0.5 * (turned[0] - turned[1]) if sees else 0.0  # finger 1 sees the turn mirrored
        # the object point on the grasp axis at the reference, now: each pad's rigid motion of its centroid
        shifts = []
        for k, (ref, pose) in enumerate(zip(self._ref, poses)):
            a = turned[k] if sees else 0.0
            c0x, c0y = ref.centroid
            ca, sa = math.cos(a), math.sin(a)
            sx = pose.centroid[0] - (ca * c0x - sa * c0y)
            sy = pose.centroid[1] - (sa * c0x + ca * c0y)
            shifts.append((sx, sy) if k == 0 else (-sx, sy))
        shift = (0.5 * (shifts[0][0] + shifts[1][0]), 0.5 * (shifts[0][1] + shifts[1][1]))
        for history, value in zip((self._history, *self._shifts), (angle, *shift)):
            history.append((t_ns, value))
            while history and t_ns - history[0][0] > self.window_ns:
                history.popleft()
        speed = math.hypot(_slope(self._shifts[0]), _slope(self._shifts[1]))
        self.motion = ObjectMotion(angle, _slope(self._history), shift, speed, sees)
        return self.motion


@dataclass(frozen=True)
class ModeOutput:
    """A mode's step: the squeeze it asks for (N), its phase, and, once it ended, why."""

    demand_n: float
    phase: str
    ended: str = ""


@dataclass(frozen=True)
class TrackGains:
    """A mode's tracking law (docs/math.md §9): ``f = f_kin − k_p e − k_d ė − k_i ∫e`` with ``e``
    how far the object is behind its reference (rad or m) and ``ė`` its rate behind the
    reference's; gains in N per unit, N·s per unit, N per unit·s. ``release_n_per_s``: how
    fast the squeeze falls from the predicted breakaway until the object moves (``moving``,
    in the unit); ``accel``: the reference's acceleration to the rate (unit/s²); ``lead_s``:
    the mode ends once the motion at its rate would reach the target in this time;
    ``regrip_margin``: the squeeze after it over the larger of the least holding squeeze and
    the kinetic one; ``overspeed``, ``overspeed_min``: faster than this times the rate and than
    ``overspeed_min`` (unit/s; the breakaway's first jerk) ends the mode and grips;
    ``weakening``: how far the object moves before its friction has fallen from static to
    sliding (the contact's slip-weakening length, in the unit; 0: at once): the feed-forward
    goes from the squeeze it broke away at to the kinetic one over it; ``max_error``: the
    reference waits for an object further behind than this (a stuck object would otherwise
    wind the squeeze down into a plunge), and if it moves slower than ``stuck`` times the rate
    it stuck again (friction back at static): release again from the squeeze it broke away
    at, not from one the lag of the squeeze would take far below it."""

    k_p: float
    k_d: float
    k_i: float
    release_n_per_s: float
    accel: float
    moving: float
    lead_s: float = 0.05
    regrip_margin: float = 1.5
    overspeed: float = 3.0
    overspeed_min: float = 0.0
    weakening: float = 0.0
    max_error: float = math.inf
    stuck: float = 0.2


BREAKAWAY_SHARE = 0.9
"""The object broke away once the load the contacts carry fell below this share of its
value at the mode's start (sliding friction carries ``μ_d/μ_s``, 0.8 on rubber)."""
PIVOT_GAINS = TrackGains(k_p=100.0, k_d=6.0, k_i=120.0, release_n_per_s=10.0, accel=30.0, moving=0.015,
                         lead_s=0.09, overspeed_min=2.0, weakening=0.04, max_error=0.05)
"""The pivot's gains (per rad), tuned in lock-step on the shipped pivot scene (docs/benchmarks.md)."""
SLIDE_GAINS = TrackGains(k_p=800.0, k_d=40.0, k_i=1600.0, release_n_per_s=10.0, accel=0.5, moving=3e-4,
                         overspeed_min=0.1, weakening=2e-4, max_error=2e-3)
"""The slide's gains (per m), tuned likewise on the shipped slide scene."""


class TrackControl:
    """Move the object by ``target`` at ``rate`` (a pivot: rad, rad/s; a slide: m, m/s), then grip.

    Phases: ``release`` (from just above the predicted breakaway squeeze, lower it until the
    object moves, or the load the contacts carry falls: it broke away), ``track`` (follow a reference that accelerates to the rate, with the squeeze
    of :class:`TrackGains` around the predicted kinetic squeeze), ``regrip`` (once the object,
    at its rate, would reach the target within ``lead_s``: the larger of the least holding and
    the kinetic squeeze times ``regrip_margin``). Guards (the object is never dropped): the
    squeeze never goes below ``floor_n``; held there for 0.3 s, or moving faster than
    ``overspeed`` times the rate, the mode ends and grips (``drop-guard``).
    """

    def __init__(self, target: float, rate: float, start_n: float, kinetic_n: float, floor_n: float, now_ns: int,
                 gains: TrackGains) -> None:
        self.target = target
        self.rate = rate
        self.gains = gains
        self.start_n = start_n
        self.kinetic_n = kinetic_n
        self.floor_n = floor_n
        self.phase = "release"
        self.ended = ""
        self._t_release = now_ns
        self._t_track: int | None = None
        self._offset = 0.0  # progress when tracking began
        self._start_rate = 0.0  # and the rate then (at most the one asked)
        self._integral = 0.0
        self._breakaway_n = start_n  # the squeeze the object broke away at
        self._release_from = start_n * 1.02  # the squeeze a release starts from
        self._released_at = 0.0  # the progress when it started
        self._last_demand = start_n
        self._ref_shift = 0.0  # how long the reference waited for the object (in the unit)
        self._last_ns = now_ns
        self._at_floor_ns: int | None = None

    def reference(self, t_ns: int) -> tuple[float, float]:
        """The reference (from where tracking began) and its rate at ``t_ns``: from the rate the
        object had then, accelerate to the rate asked, then keep it (the mode ends on the
        progress, not on the reference: a reference that stopped would brake an object lagging
        behind it)."""
        a, v, v0 = self.gains.accel, self.rate, self._start_rate
        t = 0.0 if self._t_track is None else (t_ns - self._t_track) * 1e-9
        t_ramp = (v - v0) / a
        if t < t_ramp:
            return v0 * t + 0.5 * a * t * t, v0 + a * t
        return v0 * t_ramp + 0.5 * a * t_ramp * t_ramp + v * (t - t_ramp), v

    def step(self, now_ns: int, progress: float, rate: float, hold_n: float, load_share: float = 1.0) -> ModeOutput:
        """One step: ``progress`` and ``rate`` of the object in the load's sense, ``hold_n`` the
        least holding squeeze now (N), ``load_share`` the load the contacts carry now over the
        one they carried when the mode began (the F/T sensors see the breakaway first: the load
        a contact carries falls to its sliding friction the moment it slides)."""
        dt = max(now_ns - self._last_ns, 0) * 1e-9
        self._last_ns = now_ns
        g = self.gains
        if self.phase in ("release", "track") and rate > max(g.overspeed * self.rate, g.overspeed_min):
            return self._end(f"drop-guard: moving at {rate / self.rate:.1f} times the rate asked; gripped", hold_n)
        if self.phase == "release":
            demand = self._release_from - g.release_n_per_s * (now_ns - self._t_release) * 1e-9
            # at the mode's start the F/T sensors see the breakaway first; once it moved, the load
            # has changed with the motion and only the motion tells
            broke = (progress - self._released_at >= g.moving or
                     (self._released_at == 0.0 and load_share <= BREAKAWAY_SHARE))
            if not broke:
                return self._floored(demand, now_ns, hold_n)
            self.phase, self._t_track, self._offset = "track", now_ns, progress
            self._breakaway_n = max(demand, self.floor_n)
            self._start_rate = min(max(rate, 0.0), self.rate)
            self._ref_shift = self._integral = 0.0
        if self.phase == "track":
            if progress + min(max(rate, 0.0), self.rate) * g.lead_s < self.target:
                ref, ref_rate = self.reference(now_ns)
                moved = progress - self._offset
                error = ref - self._ref_shift - moved
                if error > g.moving and rate < g.stuck * self.rate:  # stuck again: release from where it broke away
                    self.phase, self._t_release, self._released_at = "release", now_ns, progress
                    self._release_from = min(self._last_demand, self._breakaway_n)
                    return self._floored(self._release_from, now_ns, hold_n)
                if error > g.max_error:  # far behind: the reference waits
                    self._ref_shift += error - g.max_error
                    error = g.max_error
                # the integral may move the squeeze by at most a third of the kinetic squeeze: an
                # object that sticks for a while must not wind it up into a plunge
                limit = self.kinetic_n / (3.0 * g.k_i) if g.k_i > 0.0 else 0.0
                self._integral = min(max(self._integral + error * dt, -limit), limit)
                # friction falls from static to sliding over the weakening length: so does the feed-forward
                weak = math.exp(-max(moved, 0.0) / g.weakening) if g.weakening > 0.0 else 0.0
                feed = self.kinetic_n + (self._breakaway_n - self.kinetic_n) * weak
                demand = feed - g.k_p * error - g.k_d * (ref_rate - rate) - g.k_i * self._integral
                out = self._floored(demand, now_ns, hold_n)
                self._last_demand = out.demand_n
                return out
            self.phase, self.ended = "regrip", "reached"
        return ModeOutput(self._regrip_n(hold_n), "regrip", self.ended)

    def _regrip_n(self, hold_n: float) -> float:
        return max(hold_n, self.kinetic_n) * self.gains.regrip_margin

    def _end(self, why: str, hold_n: float) -> ModeOutput:
        self.phase, self.ended = "regrip", why
        return ModeOutput(self._regrip_n(hold_n), "regrip", why)

    def _floored(self, demand: float, now_ns: int, hold_n: float) -> ModeOutput:
        """``demand`` kept at or above the floor; held at the floor for 0.3 s, the mode ends and
        grips (the load needs less squeeze than holds it)."""
        if demand >= self.floor_n:
            self._at_floor_ns = None
            return ModeOutput(demand, self.phase)
        if self._at_floor_ns is None:
            self._at_floor_ns = now_ns
        if now_ns - self._at_floor_ns > 300_000_000:
            return self._end("drop-guard: the motion needs less squeeze than holds the load; gripped", hold_n)
        return ModeOutput(self.floor_n, self.phase)


class TextureOdometer:
    """The object's translation from the ridges of its face, as both pads see them move.

    A ridged face presses with ``p ∝ 1 + a·cos(k·(q − s))`` where ``s`` is how far the object
    moved: each pad's windowed Fourier coefficient at the wave vector ``k``,
    ``A = Σ w_i φ_i exp(−i k·p_i)``, turns by ``−k·s`` (docs/math.md §9). At the reference the
    wave vector of the given ``period_m`` whose coefficient is largest is found (the ridges'
    direction, each pad its own: finger 1 sees them mirrored); the phase is unwrapped frame
    to frame (a motion of less than half a period per frame). ``progress`` is the motion along
    ``direction`` (a unit vector in ``F``, the load's: where a slide goes), from the motion
    across the ridges; ``sees`` is false when a pad shows no ridges (then nothing is told).
    """

    _DIRECTIONS = 72  # candidate directions over half a turn (2.5°)

    def __init__(self, period_m: float, positions: np.ndarray, direction: tuple[float, float],
                 window_ns: int = 30_000_000, min_contrast: float = 0.05) -> None:
        self.period_m = period_m
        self.positions = positions
        self.direction = direction
        self.min_contrast = min_contrast
        x, y = positions[:, 0], positions[:, 1]
        span_x, span_y = np.ptp(x) or 1.0, np.ptp(y) or 1.0
        self._window = (np.sin(np.pi * (x - x.min()) / span_x) * np.sin(np.pi * (y - y.min()) / span_y)) ** 2 + 1e-3
        self._waves: list[np.ndarray] | None = None  # per pad: exp(−i k·p_i) at its ridges' wave vector
        self._normals: list[tuple[float, float]] = []
        self._phase = [0.0, 0.0]
        self._turned = [0.0, 0.0]
        self._history: deque[tuple[int, float]] = deque(maxlen=64)
        self.window_ns = window_ns
        self.sees = False
        self.progress = 0.0
        self.rate = 0.0

    def _coefficient(self, phi: np.ndarray, wave: np.ndarray) -> complex:
        return complex(np.dot(self._window * phi, wave))

    def update(self, t_ns: int, phi: tuple[np.ndarray, np.ndarray]) -> tuple[float, float]:
        """Take both pads' normal forces at ``t_ns``; ``(progress m, rate m/s)`` along ``direction``."""
        if self._waves is None:
            self._waves, self._normals = [], []
            for k, pad_phi in enumerate(phi):
                wave, normal, contrast = self._ridges(pad_phi)
                self._waves.append(wave)
                self._normals.append(normal if k == 0 else (-normal[0], normal[1]))
                self._phase[k] = float(np.angle(self._coefficient(pad_phi, wave)))
                self.sees = contrast >= self.min_contrast if k == 0 else self.sees and contrast >= self.min_contrast
            return 0.0, 0.0
        if not self.sees:
            return 0.0, 0.0
        k_abs = 2.0 * math.pi / self.period_m
        shifts = []
        for k, pad_phi in enumerate(phi):
            phase = float(np.angle(self._coefficient(pad_phi, self._waves[k])))
            step = phase - self._phase[k]
            step -= 2.0 * math.pi * math.floor(step / (2.0 * math.pi) + 0.5)
            self._phase[k] = phase
            self._turned[k] += step
            across = -self._turned[k] / k_abs  # the motion along the pad's ridge normal (m)
            n = self._normals[k]
            along = n[0] * self.direction[0] + n[1] * self.direction[1]
            shifts.append(across / along if abs(along) > 0.3 else math.nan)
        valid = [v for v in shifts if v == v]
        self.progress = sum(valid) / len(valid) if valid else math.nan
        self._history.append((t_ns, self.progress))
        while self._history and t_ns - self._history[0][0] > self.window_ns:
            self._history.popleft()
        self.rate = _slope(self._history)
        return self.progress, self.rate

    def _ridges(self, phi: np.ndarray) -> tuple[np.ndarray, tuple[float, float], float]:
        """The wave (per taxel), the unit normal across the ridges (the pad's frame) and the
        contrast ``|A|/Σ w φ`` of the direction whose coefficient at the period is largest."""
        k_abs = 2.0 * math.pi / self.period_m
        best = (-1.0, None, (1.0, 0.0))
        for j in range(self._DIRECTIONS):
            a = math.pi * j / self._DIRECTIONS
            n = (math.cos(a), math.sin(a))
            wave = np.exp(-1j * k_abs * (self.positions[:, 0] * n[0] + self.positions[:, 1] * n[1]))
            magnitude = abs(self._coefficient(phi, wave))
            if magnitude > best[0]:
                best = (magnitude, wave, n)
        total = float(np.dot(self._window, phi))
        return best[1], best[2], best[0] / total if total > 0 else 0.0


def _slope(history: deque) -> float:
    """Least-squares slope (per s) of ``(t_ns, value)`` pairs (0 with fewer than 3)."""
    n = len(history)
    if n < 3:
        return 0.0
    t0 = history[0][0]
    ts = [(t - t0) * 1e-9 for t, _ in history]
    mean_t = sum(ts) / n
    mean_v = sum(v for _, v in history) / n
    num = sum((t - mean_t) * (v - mean_v) for t, (_, v) in zip(ts, history))
    den = sum((t - mean_t) ** 2 for t in ts)
    return num / den if den > 0.0 else 0.0
