"""Friction identification from ramp recordings (docs/math.md §6, the paper's Fig. 4).

At (nearly) constant ``f_n`` with a slowly rising tangential load the ratio
``μ(t) = |f_t|/f_n`` rises, peaks at ``μ_s`` when slip starts and settles to ``μ_d``;
with a rising torque ``β(t) = |τ|/f_n`` (m) peaks at ``β_s`` and settles to ``β_d``.
:func:`identify_mu` and :func:`identify_beta` run one estimator on that ratio:

More in docs/modules.md, `lib/identify.py`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from enum import Enum

import numpy as np
from numpy.typing import ArrayLike
from scipy.ndimage import uniform_filter1d

from slipstack.lib.errors import ConfigError

__all__ = ["IdentifyStatus", "IdentifyConfig", "RampEstimate", "identify_mu", "identify_beta",
           "identify_mu_loadings", "identify_beta_loadings"]

_NAN = float("nan")
_MIN_FIT_SAMPLES = 5
_MIN_PLATEAU_SAMPLES = 5


class IdentifyStatus(str, Enum):
    """Outcome of an identification (compares equal to its string value)."""

    OK = "ok"
    NO_CLEAR_PEAK = "no-clear-peak"
    NO_ONSET = "no-onset"
    INSUFFICIENT_DATA = "insufficient-data"
    BAD_INPUT = "bad-input"


@dataclass(frozen=True)
class IdentifyConfig:
    """Settings of the ramp estimator (all times in s).

    Attributes:
        smooth_window_s: moving-average window for locating the peak, s.
        fit_window_s: length of the rising ramp fitted before the peak, s.
        settle_s: time after the onset skipped before the dynamic plateau, s.
        drop_sigma: the drop that marks the onset, in units of the ramp noise ``s_r``.
        min_prominence_sigma: least ``static − dynamic`` (in ``s_r``) for a clear peak.
        min_slope_t: least t-statistic of the ramp slope for a rising ramp.
        slip_threshold_m: displacement that means slip, m (force ramps).
        slip_threshold_rad: rotation that means slip, rad (torque ramps).
        slip_start_m: growth of a slip distance that ends the stick phase, m.
        slip_start_rad: growth of a slip angle that ends the stick phase, rad.
        static_window_s: length of the ramp, ending at the onset, whose line gives the
            static coefficient, s.
        min_normal_force_n: samples with smaller ``f_n`` (N) are rejected.
        sliding_fraction: with a motion signal, the dynamic level is taken only over the
            samples where it moves faster than this fraction of its mean rate after
            the onset (sliding, not the stuck phases of stick–slip); dimensionless.
        grip_fraction: loadings only: samples with ``f_n`` under this share of the grip
            (the 90th percentile of ``f_n``) are left out; dimensionless.
        active_fraction: loadings without slip flags: where the smoothed ratio is at
            least this share of its largest value; dimensionless.
    """

    smooth_window_s: float = 0.02
    fit_window_s: float = 0.5
    settle_s: float = 0.1
    drop_sigma: float = 4.0
    min_prominence_sigma: float = 3.0
    min_slope_t: float = 3.0
    slip_threshold_m: float = 1e-4
    slip_threshold_rad: float = 1e-2
    slip_start_m: float = 1e-7
    slip_start_rad: float = 1e-5
    static_window_s: float = 0.05
    min_normal_force_n: float = 1e-3
    sliding_fraction: float = 0.5
    grip_fraction: float = 0.5
    active_fraction: float = 0.5

    def __post_init__(self) -> None:
        for name in ("smooth_window_s", "fit_window_s", "drop_sigma", "min_prominence_sigma",
                     "slip_threshold_m", "slip_threshold_rad", "min_normal_force_n", "sliding_fraction",
                     "slip_start_m", "slip_start_rad", "static_window_s", "grip_fraction", "active_fraction"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ConfigError(f"identify setting {name} must be a finite number > 0, got {value!r}")
        for name in ("settle_s", "min_slope_t"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ConfigError(f"identify setting {name} must be a finite number >= 0, got {value!r}")


@dataclass(frozen=True)
class RampEstimate:
    """Static/dynamic coefficients and slip onset from one ramp.

    Attributes:
        quantity: ``"mu"`` (dimensionless) or ``"beta"`` (m).
        status: see :class:`IdentifyStatus`; ``message`` says which test decided it.
        static: ``μ_s`` / ``β_s`` (NaN if not estimated; a lower bound for ``no-onset``).
        static_se: standard error of ``static`` (same unit).
        static_model: model error of ``static`` (step 5 of the module doc; same unit).
        dynamic: ``μ_d`` / ``β_d`` (NaN if not estimated).
        dynamic_se: standard error of ``dynamic`` (same unit).
        dynamic_model: model error of ``dynamic`` (same unit).
        onset_t_s: slip-onset time, s (NaN if none).
        onset_index: index of the onset sample in the input arrays (-1 if none).
        onset_interval_s: ``(earliest, latest)`` times the onset can be at, s.
        onset_source: ``"ratio"``, ``"displacement"``, ``"slip"`` or ``"none"``.
        prominence: height of the peak above ``dynamic`` (see module doc; same unit).
        noise_std: residual std ``s_r`` of the ratio on the ramp (same unit).
        n_used: samples used; ``n_rejected``: samples rejected in step 1.
        smooth_window: moving-average window, samples.
        end_t_s: for a loading, its window's last sample (the end of its sliding), s; NaN otherwise.
    """

    quantity: str
    status: IdentifyStatus
    message: str
    static: float = _NAN
    static_se: float = _NAN
    dynamic: float = _NAN
    dynamic_se: float = _NAN
    static_model: float = _NAN
    dynamic_model: float = _NAN
    onset_t_s: float = _NAN
    onset_index: int = -1
    onset_interval_s: tuple[float, float] = (_NAN, _NAN)
    onset_source: str = "none"
    prominence: float = _NAN
    noise_std: float = _NAN
    n_used: int = 0
    n_rejected: int = 0
    smooth_window: int = 0
    end_t_s: float = _NAN

    @property
    def ok(self) -> bool:
        """True when status is ``ok``."""
        return self.status is IdentifyStatus.OK


def identify_mu(t_s: ArrayLike, f_n_n: ArrayLike, f_t_n: ArrayLike, *,
                displacement_m: ArrayLike | None = None, slip_m: ArrayLike | None = None,
                config: IdentifyConfig = IdentifyConfig()) -> RampEstimate:
    """``μ_s``, ``μ_d`` and slip onset from a tangential-force ramp.

    Args:
        t_s: sample times, s, shape ``(N,)``, strictly increasing.
        f_n_n: normal force, N, shape ``(N,)``.
        f_t_n: tangential force in ``F``, N: shape ``(N, 2)`` or magnitudes ``(N,)``.
        displacement_m: optional object displacement along the load, m, ``(N,)``
            or ``(N, 2)`` (its norm is used).
        slip_m: optional slip distance after the elastic pre-slip, m, ``(N,)``
            (takes precedence over ``displacement_m``).
        config: estimator settings.
    """
    if slip_m is not None:
        return _identify("mu", t_s, f_n_n, f_t_n, slip_m, config.slip_start_m, config, from_slip=True)
    return _identify("mu", t_s, f_n_n, f_t_n, displacement_m, config.slip_threshold_m, config)


def identify_beta(t_s: ArrayLike, f_n_n: ArrayLike, tau_nm: ArrayLike, *,
                  rotation_rad: ArrayLike | None = None, slip_rad: ArrayLike | None = None,
                  config: IdentifyConfig = IdentifyConfig()) -> RampEstimate:
    """``β_s``, ``β_d`` (m) and slip onset from a torque ramp (``|τ|/f_n``).

    Args:
        t_s: sample times, s, shape ``(N,)``, strictly increasing.
        f_n_n: normal force, N, shape ``(N,)``.
        tau_nm: torque about the pad normal, N·m, shape ``(N,)``.
        rotation_rad: optional object rotation about the normal, rad, ``(N,)``.
        slip_rad: optional slip angle after the elastic twist, rad, ``(N,)`` (takes
            precedence over ``rotation_rad``).
        config: estimator settings.
    """
    if slip_rad is not None:
        return _identify("beta", t_s, f_n_n, tau_nm, slip_rad, config.slip_start_rad, config, from_slip=True)
    return _identify("beta", t_s, f_n_n, tau_nm, rotation_rad, config.slip_threshold_rad, config)


def identify_mu_loadings(t_s: ArrayLike, f_n_n: ArrayLike, f_t_n: ArrayLike, *,
                         gross_slip: ArrayLike | None = None, slip_m: ArrayLike | None = None,
                         config: IdentifyConfig = IdentifyConfig()) -> tuple[RampEstimate, ...]:
    """:func:`identify_mu` on each loading of a whole recording (module docstring).

    Args are those of :func:`identify_mu`, and ``gross_slip``: optional per-sample flags
    of true gross slip, shape ``(N,)``. Returns one estimate per loading, in time order
    (``onset_index`` into the input arrays); without any loading, one estimate of the
    whole record (its status says why: ``no-onset`` for a load that never slips).
    """
    return _loadings("mu", t_s, f_n_n, f_t_n, gross_slip, slip_m, config.slip_start_m, config)


def identify_beta_loadings(t_s: ArrayLike, f_n_n: ArrayLike, tau_nm: ArrayLike, *,
                           gross_slip: ArrayLike | None = None, slip_rad: ArrayLike | None = None,
                           config: IdentifyConfig = IdentifyConfig()) -> tuple[RampEstimate, ...]:
    """:func:`identify_beta` on each loading of a whole recording (see :func:`identify_mu_loadings`)."""
    return _loadings("beta", t_s, f_n_n, tau_nm, gross_slip, slip_rad, config.slip_start_rad, config)


# ---------------------------------------------------------------- implementation


def _magnitude(a: np.ndarray, n: int) -> np.ndarray | None:
    """``|a|`` per sample for shape ``(n,)`` or ``(n, k)``; None on any other shape."""
    if a.ndim == 1 and a.shape[0] == n:
        return np.abs(a)
    if a.ndim == 2 and a.shape[0] == n:
        return np.sqrt(np.sum(a * a, axis=1))
    return None


def _from_start(a: np.ndarray) -> np.ndarray:
    """``a`` minus its first finite sample (displacement from the start); a difference beyond
    float range is +-inf, which the estimators treat as any other non-finite sample."""
    rows = a if a.ndim > 1 else a[:, None] if a.ndim == 1 else a.reshape(1, -1)
    finite = np.flatnonzero(np.all(np.isfinite(rows), axis=1))
    if not finite.size:
        return a
    with np.errstate(over="ignore"):
        return a - a[finite[0]]


def _identify(quantity: str, t_raw: ArrayLike, fn_raw: ArrayLike, load_raw: ArrayLike,
              motion_raw: ArrayLike | None, motion_threshold: float,
              cfg: IdentifyConfig, *, from_slip: bool = False) -> RampEstimate:
    try:
        t = np.asarray(t_raw, dtype=float)
        fn = np.asarray(fn_raw, dtype=float)
        load_arr = np.asarray(load_raw, dtype=float)
        motion_arr = None if motion_raw is None else np.asarray(motion_raw, dtype=float)
    except (TypeError, ValueError) as exc:
        return RampEstimate(quantity, IdentifyStatus.BAD_INPUT, f"inputs are not numeric arrays: {exc}")
    n = t.shape[0] if t.ndim == 1 else -1
    load = _magnitude(load_arr, n)
    motion = None if motion_arr is None else _magnitude(_from_start(motion_arr), n)
    if n < 0 or fn.shape != (n,) or load is None or (motion_arr is not None and motion is None):
        return RampEstimate(quantity, IdentifyStatus.BAD_INPUT,
                            f"shapes do not match: t {t.shape}, f_n {fn.shape}, load {load_arr.shape}")
    with np.errstate(all="ignore"):
        keep = np.isfinite(t) & np.isfinite(fn) & np.isfinite(load) & (fn >= cfg.min_normal_force_n)
        keep &= np.isfinite(load / np.where(keep, fn, 1.0))
        if motion is not None:
            keep &= np.isfinite(motion)
    index = np.flatnonzero(keep)
    n_rejected = n - index.size
    if index.size < 2 * _MIN_FIT_SAMPLES:
        return RampEstimate(quantity, IdentifyStatus.INSUFFICIENT_DATA,
                            f"{index.size} valid samples (f_n >= {cfg.min_normal_force_n} N, finite)",
                            n_used=int(index.size), n_rejected=n_rejected)
    t, ratio = t[index], load[index] / fn[index]
    dt = np.diff(t)
    if not np.all(dt > 0.0):
        return RampEstimate(quantity, IdentifyStatus.BAD_INPUT, "time stamps are not strictly increasing",
                            n_used=int(index.size), n_rejected=n_rejected)
    step = float(np.median(dt))
    with np.errstate(all="ignore"):  # absurd magnitudes give a status, not warnings
        return _RampFit(quantity, t, ratio, None if motion is None else motion[index], motion_threshold,
                        index, n_rejected, step, cfg, from_slip).run()


def _loadings(quantity: str, t_raw: ArrayLike, fn_raw: ArrayLike, load_raw: ArrayLike, gross_raw: ArrayLike | None,
              slip_raw: ArrayLike | None, slip_start: float, cfg: IdentifyConfig) -> tuple[RampEstimate, ...]:
    """The estimator on each loading's window, ``f_n`` under the grip left out (module docstring)."""
    try:
        t = np.asarray(t_raw, dtype=float)
        fn = np.asarray(fn_raw, dtype=float)
        load = _magnitude(np.asarray(load_raw, dtype=float), t.shape[0] if t.ndim == 1 else -1)
        gross = None if gross_raw is None else np.asarray(gross_raw, dtype=bool)
        slip = None if slip_raw is None else np.asarray(slip_raw, dtype=float)
    except (TypeError, ValueError) as exc:
        return (RampEstimate(quantity, IdentifyStatus.BAD_INPUT, f"inputs are not numeric arrays: {exc}"),)
    n = t.shape[0] if t.ndim == 1 else -1
    if (n < 0 or fn.shape != (n,) or load is None or (gross is not None and gross.shape != (n,))
            or (slip is not None and slip.shape[:1] != (n,))):
        return (_identify(quantity, t, fn, load_raw, slip, slip_start, cfg, from_slip=True),)
    with np.errstate(all="ignore"):
        usable = np.isfinite(fn) & (fn >= cfg.min_normal_force_n) & np.isfinite(load) & np.isfinite(t)
        grip = float(np.percentile(fn[usable], 90)) if usable.any() else 0.0
        loaded = usable & (fn >= cfg.grip_fraction * grip)
        fn_loaded = np.where(loaded, fn, np.nan)
        ratio = load / np.where(loaded, fn, 1.0)
    if gross is not None:
        windows = _slip_windows(t, gross & loaded, cfg)
    else:
        windows = _ratio_windows(t, ratio, loaded, cfg)
    whole = (0, n)
    ests = []
    for a, b in windows or [whole]:
        est = _identify(quantity, t[a:b], fn_loaded[a:b], load[a:b], None if slip is None else slip[a:b],
                        slip_start, cfg, from_slip=True)
        ests.append(replace(est, onset_index=est.onset_index + a if est.onset_index >= 0 else -1,
                            end_t_s=float(t[b - 1]) if windows else _NAN))
    return tuple(ests)


def _slip_windows(t: np.ndarray, gross: np.ndarray, cfg: IdentifyConfig) -> list[tuple[int, int]]:
    """``[start, stop)`` per loading from true gross-slip flags: runs of slip less than
    ``fit_window_s`` apart are one loading; each window ends at its last sliding sample."""
    edges = np.flatnonzero(np.diff(np.concatenate([[False], gross, [False]]).astype(np.int8)))
    runs: list[list[int]] = []
    for a, b in zip(edges[::2], edges[1::2]):
        if runs and t[a] - t[runs[-1][1] - 1] < cfg.fit_window_s:
            runs[-1][1] = int(b)
        else:
            runs.append([int(a), int(b)])
    starts = [0] + [b for _, b in runs[:-1]]
    return [(start, b) for start, (_, b) in zip(starts, runs)]


def _ratio_windows(t: np.ndarray, ratio: np.ndarray, loaded: np.ndarray,
                   cfg: IdentifyConfig) -> list[tuple[int, int]]:
    """``[start, stop)`` per loading from the ratio alone (module docstring): a stretch
    where the smoothed ratio is at least ``active_fraction`` of its largest value (dips
    shorter than ``fit_window_s`` bridged), ending where its plateau ends: from
    ``settle_s`` after its top (the first sample within 3 noise of it) to where the ratio falls under half that share, the knee
    of a level followed by a straight fall (:func:`_hinge` on the reversed stretch), if
    the fall is significant (t ≥ ``min_slope_t``), so that the unload is left out."""
    index = np.flatnonzero(loaded & np.isfinite(ratio))
    if index.size < 2 * _MIN_FIT_SAMPLES or not np.all(np.diff(t[index]) > 0):
        return []
    r, tt = ratio[index], t[index]
    step = float(np.median(np.diff(tt)))
    w = 2 * int(round(cfg.smooth_window_s / step / 2.0)) + 1
    smooth = uniform_filter1d(r, w, mode="nearest")
    active = smooth >= cfg.active_fraction * float(smooth.max())
    edges = np.flatnonzero(np.diff(np.concatenate([[False], active, [False]]).astype(np.int8)))
    runs: list[list[int]] = []
    for a, b in zip(edges[::2], edges[1::2]):
        if runs and tt[a] - tt[runs[-1][1] - 1] < cfg.fit_window_s:
            runs[-1][1] = int(b)  # a dip shorter than a ramp: the same loading
        else:
            runs.append([int(a), int(b)])
    settle = int(round(cfg.settle_s / step))
    low = smooth < cfg.active_fraction / 2.0 * float(smooth.max())
    windows, start = [], 0
    noise = float(np.std(np.diff(r)) / math.sqrt(2.0 * w))  # of the smoothed ratio
    for i, (a, b) in enumerate(runs):
        peak = a + int(np.argmax(smooth[a:b] >= smooth[a:b].max() - 3.0 * noise))  # a flat top: its start
        rest = np.flatnonzero(low[b:runs[i + 1][0] if i + 1 < len(runs) else r.size])
        end = b + int(rest[0]) + 1 if rest.size else (runs[i + 1][0] if i + 1 < len(runs) else r.size)
        stop, first = b, peak + settle
        if end - first > 2 * _MIN_FIT_SAMPLES:
            k, t_stat = _hinge(-tt[first:end][::-1], r[first:end][::-1])
            if t_stat >= cfg.min_slope_t:
                stop = min(end - k, b)
        windows.append((start, int(index[stop - 1]) + 1))
        start = int(index[stop - 1]) + 1
    return windows


class _RampFit:
    """One estimation on clean, sorted samples; ``index`` maps back to the input."""

    def __init__(self, quantity: str, t: np.ndarray, ratio: np.ndarray, motion: np.ndarray | None,
                 motion_threshold: float, index: np.ndarray, n_rejected: int, step: float,
                 cfg: IdentifyConfig, from_slip: bool = False) -> None:
        self.quantity, self.t, self.r, self.motion = quantity, t, ratio, motion
        self.from_slip = from_slip
        self.static_len = max(_MIN_FIT_SAMPLES, int(round(cfg.static_window_s / step)))
        self.motion_threshold, self.index, self.cfg = motion_threshold, index, cfg
        self.w = 2 * int(round(cfg.smooth_window_s / step / 2.0)) + 1
        self.fit_len = max(_MIN_FIT_SAMPLES, int(round(cfg.fit_window_s / step)))
        self.settle = int(round(cfg.settle_s / step))
        self.common = {"n_used": int(t.size), "n_rejected": n_rejected, "smooth_window": self.w}

    def result(self, status: IdentifyStatus, message: str, **fields: object) -> RampEstimate:
        return RampEstimate(self.quantity, status, message, **fields, **self.common)  # type: ignore[arg-type]

    def _sliding(self, values: np.ndarray, start: int) -> np.ndarray:
        """``values[start:]``, kept only where the motion signal shows sliding (if there is
        one and enough such samples): stick–slip's stuck phases would bias the dynamic level."""
        plateau = values[start:]
        if self.motion is None or plateau.size < _MIN_PLATEAU_SAMPLES:
            return plateau
        rate = np.gradient(self.motion[start:], self.t[start:])
        mean_rate = float(np.mean(rate))
        sliding = rate > self.cfg.sliding_fraction * mean_rate if mean_rate > 0 else np.zeros(rate.shape, bool)
        return plateau[sliding] if np.count_nonzero(sliding) >= _MIN_PLATEAU_SAMPLES else plateau

    def run(self) -> RampEstimate:
        n, h = self.r.size, self.w // 2
        smooth = uniform_filter1d(self.r, self.w, mode="nearest")
        moved = None
        if self.motion is not None:
            crossed = np.flatnonzero(self.motion > self.motion_threshold)
            if crossed.size == 0:
                unit = "m" if self.quantity == "mu" else "rad"
                return self.result(IdentifyStatus.NO_ONSET,
                                   f"motion never exceeds {self.motion_threshold:g} {unit}",
                                   static=float(smooth.max()))
            moved = int(crossed[0])
        limit = n if moved is None else min(n, moved + self.w + 1)
        k_peak = int(np.argmax(smooth[:limit]))
        if moved is None and k_peak >= n - 1 - self.w - self.settle - _MIN_PLATEAU_SAMPLES:
            return self._knee(float(smooth[k_peak]), "ratio peaks at the end of the record, "
                              "too late for a settled plateau")
        fit_end = max(0, k_peak - h)
        fit_start = max(0, fit_end - self.fit_len)
        if fit_end - fit_start < _MIN_FIT_SAMPLES:
            return self.result(IdentifyStatus.INSUFFICIENT_DATA,
                               f"only {fit_end - fit_start} ramp samples before the peak")
        line = _LineFit(self.t[fit_start:fit_end], self.r[fit_start:fit_end])
        flat = not line.slope_t >= self.cfg.min_slope_t
        if flat and moved is None and not self._drops_after(k_peak, line):
            return self._knee(float(smooth[k_peak]), f"ratio does not rise before its peak (slope t = "
                              f"{line.slope_t:.2f} < {self.cfg.min_slope_t})")
        onset, lo, source = self._onset(line, fit_end, k_peak, moved)
        onset_line = line  # the crossing-based displacement onset keeps the ramp's line
        if self.from_slip or source == "ratio":
            up_to_onset = slice(max(0, onset + 1 - self.static_len), onset + 1)
            if onset + 1 - up_to_onset.start >= _MIN_FIT_SAMPLES:
                onset_line = _LineFit(self.t[up_to_onset], self.r[up_to_onset])
        static = float(onset_line.at(self.t[onset]))
        static_model = self._bend(onset, static)
        plateau = self._sliding(self.r, min(n, onset + 1 + self.settle))
        common = dict(static=static, static_se=onset_line.se_at(self.t[onset]), onset_t_s=float(self.t[onset]),
                      onset_index=int(self.index[onset]), onset_source=source, noise_std=line.s_r,
                      onset_interval_s=(float(self.t[lo]), float(self.t[min(onset + 1, n - 1)])))
        if plateau.size < _MIN_PLATEAU_SAMPLES:
            return self.result(IdentifyStatus.INSUFFICIENT_DATA,
                               f"only {plateau.size} samples after onset + settle ({self.cfg.settle_s} s)",
                               **common)
        dynamic, dynamic_se, drift = _sliding_level(plateau)
        common.update(static_model=static_model, dynamic_model=drift)
        prominence = min(static, float(smooth[k_peak])) - dynamic
        if not prominence >= self.cfg.min_prominence_sigma * line.s_r:
            if moved is not None:  # the motion gives the onset: a contact without a drop
                return self.result(IdentifyStatus.OK, f"no drop (static ~ dynamic): static - dynamic = "
                                   f"{prominence:.3g}, onset from the motion", dynamic=dynamic,
                                   dynamic_se=dynamic_se, prominence=prominence, **common)
            knee = self._knee(float(smooth[k_peak]), "no drop")
            if knee.status is IdentifyStatus.NO_CLEAR_PEAK:  # a ramp that levels off
                return knee
            return self.result(IdentifyStatus.NO_CLEAR_PEAK,
                               f"static - dynamic = {prominence:.4g} < {self.cfg.min_prominence_sigma} "
                               f"x noise {line.s_r:.3g}", dynamic=dynamic, dynamic_se=dynamic_se,
                               prominence=prominence, **common)
        return self.result(IdentifyStatus.OK, f"peak {prominence / max(line.s_r, 1e-300):.1f} x noise",
                           dynamic=dynamic, dynamic_se=dynamic_se, prominence=prominence, **common)

    def _drops_after(self, k_peak: int, line: "_LineFit") -> bool:
        """Whether the ratio falls clearly after ``k_peak``: the mean from ``settle_s`` after it
        on lies under the ramp's line by ``min_prominence_sigma`` × its noise (a ratio that
        levelled off before its peak, creeping or in stick–slip, and then dropped)."""
        after = self.r[min(k_peak + self.settle, self.r.size):]
        return after.size >= _MIN_PLATEAU_SAMPLES and bool(
            float(line.at(self.t[k_peak])) - float(after.mean()) >= self.cfg.min_prominence_sigma * line.s_r)

    def _bend(self, onset: int, static: float) -> float:
        """``|static − the value at the onset of a line over the last half of its window|``."""
        last_half = slice(max(0, onset + 1 - self.static_len // 2), onset + 1)
        if last_half.stop - last_half.start < _MIN_FIT_SAMPLES:
            return math.nan
        return abs(static - float(_LineFit(self.t[last_half], self.r[last_half]).at(self.t[onset])))

    def _knee(self, peak: float, why: str) -> RampEstimate:
        """No rising ramp right before a peak: look for a ramp that levels off (a knee).

        Fits ``r ≈ a + b·min(t − t_k, 0)`` over the whole record. A significant rise
        (slope t-statistic ``≥ min_slope_t``) followed by at least ``fit_window_s`` of
        level ratio means it levels off without a drop: slip with ``μ_s ≈ μ_d``, or a
        load that stopped rising — only a displacement can tell. Reported as
        ``no-clear-peak`` with ``static = dynamic`` = the level after the knee, onset =
        the knee. Otherwise ``no-onset`` (``why``), ``static`` = ``peak``, a lower bound.
        """
        k, knee_t = _hinge(self.t, self.r)
        plateau = self.r[k:]
        if not (knee_t >= self.cfg.min_slope_t and k >= _MIN_FIT_SAMPLES
                and plateau.size >= max(self.fit_len, _MIN_PLATEAU_SAMPLES)):
            return self.result(IdentifyStatus.NO_ONSET, f"{why}; no knee either", static=peak)
        dynamic, dynamic_se, drift = _sliding_level(plateau)
        return self.result(IdentifyStatus.NO_CLEAR_PEAK,
                           "ratio levels off without a drop (static ~ dynamic, or the load stopped "
                           "rising: pass the displacement to tell)", static=dynamic, static_se=dynamic_se,
                           dynamic=dynamic, dynamic_se=dynamic_se, static_model=drift, dynamic_model=drift,
                           onset_t_s=float(self.t[k]),
                           onset_index=int(self.index[k]), onset_source="ratio", prominence=0.0,
                           onset_interval_s=(float(self.t[max(k - self.w, 0)]),
                                             float(self.t[min(k + self.w, self.r.size - 1)])))

    def _onset(self, line: "_LineFit", fit_end: int, k_peak: int, moved: int | None) -> tuple[int, int, str]:
        """(onset, earliest, source): onset = last sample on the ramp before the drop."""
        if moved is not None and self.from_slip:
            resting = np.flatnonzero(self.motion[:moved] <= self.motion_threshold)
            last = int(resting[-1]) if resting.size else max(moved - 1, 0)
            return last, last, "slip"
        if moved is not None:
            return max(moved - 1, 0), max(moved - 1, 0), "displacement"
        n = self.r.size
        stop = min(n, k_peak + 2 * self.w + self.fit_len)
        span = np.arange(fit_end, stop)
        under = self.r[span] < line.at(self.t[span]) - self.cfg.drop_sigma * line.s_r
        below = under[:-1] & under[1:]  # two in a row: one noise spike is not a drop
        if not below.any():  # no resolved drop: the peak of the smoothed ratio
            return k_peak, max(fit_end, k_peak - self.w // 2), "ratio"
        first = int(span[np.argmax(below)])
        on_line = np.flatnonzero(self.r[fit_end:first] >= line.at(self.t[fit_end:first]) - line.s_r)
        earliest = fit_end + int(on_line[-1]) if on_line.size else fit_end
        return earliest, earliest, "ratio"


class _LineFit:
    """Least-squares line ``r ≈ a + b (t − t̄)`` with prediction standard errors."""

    def __init__(self, t: np.ndarray, r: np.ndarray) -> None:
        self.t_mean = float(t.mean())
        dt = t - self.t_mean
        self.sxx = float(dt @ dt)
        self.n = t.size
        self.a = float(r.mean())
        self.b = float(dt @ (r - self.a) / self.sxx) if self.sxx > 0 else 0.0
        resid = r - self.a - self.b * dt
        self.s_r = float(math.sqrt(resid @ resid / max(self.n - 2, 1)))
        se_b = self.s_r / math.sqrt(self.sxx) if self.sxx > 0 else math.inf
        self.slope_t = self.b / se_b if se_b > 0 else (math.inf if self.b > 0 else 0.0)

    def at(self, t: np.ndarray | float) -> np.ndarray | float:
        return self.a + self.b * (t - self.t_mean)

    def se_at(self, t: float) -> float:
        """Standard error of the fitted mean at ``t``."""
        return self.s_r * math.sqrt(1.0 / self.n + (t - self.t_mean) ** 2 / self.sxx)


def _hinge(t: np.ndarray, r: np.ndarray) -> tuple[int, float]:
    """Best knee ``k`` of ``r ≈ a + b·min(t − t_k, 0)``: ``(k, t-statistic of b)``.

    All breakpoints are scored at once from prefix sums (O(N)).
    """
    n = t.size
    t, r = t - t.mean(), r - r.mean()  # centred: the prefix sums below cancel less
    k = np.arange(1, n - 1)
    tk = t[k]
    ct, ctt = np.cumsum(t), np.cumsum(t * t)
    ctr, cr = np.cumsum(t * r), np.cumsum(r)
    sx = ct[k - 1] - k * tk  # sums over i < k of x_i = t_i − t_k
    sxx = ctt[k - 1] - 2.0 * tk * ct[k - 1] + k * tk * tk
    sxr = ctr[k - 1] - tk * cr[k - 1]
    sr, srr = cr[-1], float(r @ r)
    vxx = sxx - sx * sx / n
    vxy = sxr - sx * sr / n
    vyy = srr - sr * sr / n
    sse = np.where(vxx > 0, vyy - vxy * vxy / vxx, np.inf)  # caller silences 0/0 warnings
    best = int(np.argmin(sse))
    if not (vxx[best] > 0 and math.isfinite(sse[best])):
        return int(k[best]), 0.0
    b = vxy[best] / vxx[best]
    s_r = math.sqrt(max(float(sse[best]), 0.0) / max(n - 2, 1))
    t_stat = b * math.sqrt(vxx[best]) / s_r if s_r > 0 else (math.inf if b > 0 else 0.0)
    return int(k[best]), float(t_stat)


def _sliding_level(plateau: np.ndarray) -> tuple[float, float, float]:
    """(level, its standard error, drift): the mean of the plateau's second half (the
    whole plateau if that half is too short), and how much that half still drifts, the
    difference between the means of its own two halves."""
    late = plateau[plateau.size // 2:]
    if late.size < _MIN_PLATEAU_SAMPLES:
        late = plateau
    level, se = _mean_ar1(late)
    half = late.size // 2
    return level, se, abs(float(late[:half].mean()) - float(late[half:].mean())) if half else 0.0


def _mean_ar1(x: np.ndarray) -> tuple[float, float]:
    """Mean and its standard error corrected for lag-1 autocorrelation ``ρ ∈ [0, 0.99]``."""
    mean = float(x.mean())
    d = x - mean
    var = float(d @ d)
    rho = float(d[1:] @ d[:-1] / var) if var > 0 else 0.0
    rho = min(max(rho, 0.0), 0.99)
    se = math.sqrt(var / (x.size - 1) / x.size) * math.sqrt((1 + rho) / (1 - rho))
    return mean, se
