"""``slipstack identify RECORDING... -o material.toml``: a material file from friction ramps.

More in docs/modules.md, `analysis/identify_cli.py`.
"""

from __future__ import annotations

import argparse
import datetime
import math
import sys
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable

import numpy as np

from slipstack.lib.episodes import find_episodes
from slipstack.lib.errors import DecodeError
from slipstack.lib.limit_set import load_factor
from slipstack.lib.onset_band import load_path, pressure_spread
from slipstack.lib.identify import RampEstimate
from slipstack.lib.material import DELTA_MAX, Material, detector_thresholds, implausible, material_toml
from slipstack.lib.output_file import output_file
from slipstack.lib.material_fit import (beta_from_pressure, frame_noise, interval_half_width, onset_frames,
                                         pooled, pooled_model)
from slipstack.lib.pad import PadGeometry
from slipstack.messages import decode
from slipstack.nodes.recording.bag_io import RecordingError, read_recording
from slipstack.analysis.report import Identification, RecordingSeries, format_identification, identify_recording, load_series

__all__ = ["IdentifiedRecording", "IdentificationRefused", "identify_material", "add_parser", "main_identify"]

_STICK_WINDOW_NS = 300_000_000
_STICK_GUARD_NS = 20_000_000
_SLIDE_SETTLE_NS = 100_000_000
_EPISODE_GAP_NS = 20_000_000
_MIN_F_N = 0.1  # N: frames with less normal force carry no load factor

Progress = Callable[[str], None]


@dataclass(frozen=True)
class IdentifiedRecording:
    """One recording: its path, its report columns and its ramp identification."""

    path: Path
    series: RecordingSeries
    ident: Identification

    @property
    def torsion(self) -> bool:
        return self.ident.load == "torque"

    @property
    def loadings(self) -> tuple[RampEstimate, ...]:
        """The estimate of each loading: β for a torque ramp, μ otherwise (a combined
        ramp's μ only places its loadings)."""
        return self.ident.beta if self.torsion else self.ident.mu


def _onsets_ns(rec: IdentifiedRecording) -> list[int]:
    """Every gross-slip onset: the truth's episodes, else each loading's estimated onset."""
    series = rec.series
    if series.has("rig/truth"):
        truth = series["rig/truth"]
        return [e.start_ns for e in find_episodes(truth["stamp_ns"], truth["gross_slip"].astype(bool),
                                                  min_gap_ns=_EPISODE_GAP_NS)]
    return [series.t0_ns + round(e.onset_t_s * 1e9) for e in rec.loadings if math.isfinite(e.onset_t_s)]


def _tactile_frames(path: Path) -> list:
    frames = []
    for frame in read_recording(path, ["tactile/frame"]):
        try:
            frames.append(decode(frame.payload))
        except DecodeError:
            continue
    return frames


@dataclass(frozen=True)
class _Frames:
    """The detector's view of a recording, per frame: stamps (ns), γ, load path and
    pressure spread (NaN without a pressure frame), and what γ was computed from."""

    stamps: np.ndarray
    gamma: np.ndarray
    path: np.ndarray
    spread: np.ndarray
    source: str


def _gamma_series(rec: IdentifiedRecording, mu_s: float, beta_s_m: float) -> _Frames:
    """The recording's frames: exact γ on tactile frames, else the F/T ratio."""
    w = rec.series["ft/wrench"]
    ok = w["usable"].astype(bool) & (w["f_n"] > _MIN_F_N)
    ft_ns, f_n, f_t, tau = w["stamp_ns"][ok], w["f_n"][ok].astype(float), w["f_t"][ok].astype(float), w["tau"][ok]
    frames = [m for m in _tactile_frames(rec.path) if m.status == "ok"] if math.isfinite(mu_s) else []
    if frames and ft_ns.size:
        rows = []
        pad = PadGeometry(frames[0].rows, frames[0].cols, frames[0].pitch_m)
        for m in frames:
            k = int(np.clip(np.searchsorted(ft_ns, m.header.stamp_ns), 1, ft_ns.size - 1))
            k = k if abs(ft_ns[k] - m.header.stamp_ns) < abs(ft_ns[k - 1] - m.header.stamp_ns) else k - 1
            p = np.where(m.dead, 0.0, np.maximum(m.pressure_pa.astype(float), 0.0))
            if p.sum() <= 0 or (m.rows, m.cols) != (pad.rows, pad.cols):
                continue
            phi = f_n[k] * p / p.sum()
            r = load_factor(phi, pad.positions, f_t[k], float(tau[k]), mu_s)
            if r.status.usable:
                rows.append((m.header.stamp_ns, r.gamma, load_path(float(np.hypot(*f_t[k])), float(tau[k]), mu_s,
                                                                   beta_s_m), pressure_spread(phi)))
        stamps, gamma, path, spread = (np.array(c) for c in zip(*rows)) if rows else (np.zeros(0),) * 4
        return _Frames(stamps.astype(np.int64), gamma, path, spread, "exact (tactile)")
    force = np.hypot(f_t[:, 0], f_t[:, 1])
    path = np.array([load_path(f, t, mu_s, beta_s_m) for f, t in zip(force.tolist(), tau.tolist())])
    ratio = np.abs(tau) / f_n / beta_s_m if rec.torsion else force / f_n / mu_s
    return _Frames(ft_ns, ratio, path, np.full(ft_ns.size, math.nan), "ratio (F/T only)")


def _sliding_mask(rec: IdentifiedRecording, stamps_ns: np.ndarray) -> np.ndarray:
    """Frames sliding for good: from 100 ms after each gross-slip onset to the slip's end
    (the truth's episodes, else each loading's onset to the end of its plateau)."""
    if rec.series.has("rig/truth"):
        truth = rec.series["rig/truth"]
        spans = [(e.start_ns, e.end_ns) for e in find_episodes(truth["stamp_ns"], truth["gross_slip"].astype(bool),
                                                               min_gap_ns=_EPISODE_GAP_NS)]
    else:
        t0 = rec.series.t0_ns
        spans = [(t0 + round(e.onset_t_s * 1e9), t0 + round(e.end_t_s * 1e9)) for e in rec.loadings
                 if math.isfinite(e.onset_t_s) and math.isfinite(e.end_t_s)]
    mask = np.zeros(stamps_ns.shape, dtype=bool)
    for start, end in spans:
        mask |= (stamps_ns >= start + _SLIDE_SETTLE_NS) & (stamps_ns <= end)
    return mask


@dataclass(frozen=True)
class _Pooled:
    """A pooled coefficient: value, standard error and model error (same unit)."""

    value: float
    se: float
    model: float = math.nan

    def with_route(self, other_route: float) -> _Pooled:
        """This estimate with its disagreement with ``other_route`` added to the model error."""
        if not math.isfinite(other_route):
            return self
        own = self.model if math.isfinite(self.model) else 0.0
        return _Pooled(self.value, self.se, math.hypot(own, self.value - other_route))

    def text(self, scale: float = 1.0, unit: str = "") -> str:
        """``value ± se (stat) ± model (model)``, and the ± 2-sigma interval in % of the value."""
        half = interval_half_width(self.se, self.model)
        share = f"{100 * half / abs(self.value):.1f} %" if self.value else "-"
        return (f"{self.value * scale:.4f} ± {self.se * scale:.4f} (stat) ± {self.model * scale:.4f} (model)"
                f"{unit} [± 2 sigma: {share}]")


def _estimates(recs: list[IdentifiedRecording]) -> list[RampEstimate]:
    """The loadings of ``recs`` that gave both a static and a dynamic value."""
    return [e for r in recs for e in r.loadings if math.isfinite(e.static) and math.isfinite(e.dynamic)]


def _pool(ests: list[RampEstimate]) -> tuple[_Pooled, _Pooled]:
    static = pooled([e.static for e in ests], [e.static_se for e in ests])
    dynamic = pooled([e.dynamic for e in ests], [e.dynamic_se for e in ests])
    return (_Pooled(*static, pooled_model([e.static for e in ests], [e.static_model for e in ests])),
            _Pooled(*dynamic, pooled_model([e.dynamic for e in ests], [e.dynamic_model for e in ests])))


def _spread(ests: list[RampEstimate], scale: float, unit: str) -> str:
    """The loadings' static and dynamic values, min–max, and their sliding levels."""
    if len(ests) < 2:
        return f"{len(ests)} loading"
    st = [e.static * scale for e in ests]
    dy = [e.dynamic * scale for e in ests]
    lv = [e.dynamic / e.static for e in ests]
    return (f"{len(ests)} loadings: static {min(st):.4f}–{max(st):.4f}{unit}, dynamic {min(dy):.4f}–"
            f"{max(dy):.4f}{unit}, dynamic/static {min(lv):.3f}–{max(lv):.3f}")


def _pressure_frames(rec: IdentifiedRecording, stamps_ns: np.ndarray, keep: np.ndarray) -> list[np.ndarray]:
    """The recording's usable pressure frames whose stamps are in ``stamps_ns[keep]``."""
    wanted = set(stamps_ns[keep].tolist())
    return [np.where(m.dead, 0.0, np.maximum(m.pressure_pa.astype(float), 0.0))
            for m in _tactile_frames(rec.path) if m.status == "ok" and m.header.stamp_ns in wanted]


_RECORD_FORCE = ("record one with `slipstack launch scene:=ident_force controller:=false recording:=force.mcap` "
                 "(on hardware: press, pull until the object slides for a second, hold, let go)")
_RECORD_TORQUE = ("record one with `slipstack launch scene:=ident_torsion controller:=false recording:=torsion.mcap` "
                  "(on hardware: press, twist until the object turns for a second, hold, let go)")


class IdentificationRefused(RecordingError):
    """The recordings give an implausible material; ``material`` and ``lines`` are what
    they give (``--force`` writes it, marked), ``reasons`` why it is refused."""

    def __init__(self, reasons: list[str], material: Material, lines: list[str]) -> None:
        super().__init__("the identification is refused: " + "; ".join(reasons)
                         + " (--force writes it anyway, marked as refused)")
        self.reasons, self.material, self.lines = reasons, material, lines


def identify_material(paths: list[Path], *, name: str, provenance: str = "",
                      progress: Progress | None = None) -> tuple[Material, list[str]]:
    """The material of the recordings and the report lines (one block per recording).

    Raises:
        RecordingError: a recording cannot be read or has no usable ``ft/wrench``, none of
            the recordings is a force ramp (``μ_s`` is needed for the rest), or none of the
            force ramps slides (no onset: no ``μ_s``, ``μ_d``).
        IdentificationRefused: the result is implausible (:func:`_implausible`).
    """
    say = progress or (lambda _msg: None)
    recs = []
    for i, path in enumerate(paths, 1):
        say(f"[{i}/{len(paths)}] {path.name}: reading and fitting")
        series = load_series(path).within_scene()
        recs.append(IdentifiedRecording(path, series, identify_recording(series)))
    forces = [r for r in recs if r.ident.load == "force"]
    torsions = [r for r in recs if r.torsion]
    if not forces:
        raise RecordingError(f"no tangential-force ramp among {', '.join(p.name for p in paths)}: μ_s is needed; "
                             + _RECORD_FORCE)
    force_ests, torsion_ests = _estimates(forces), _estimates(torsions)
    if not force_ests:
        found = "; ".join(f"{r.path.name}: {e.status.value} ({e.message})" for r in forces for e in r.loadings)
        raise RecordingError(f"no slip onset in the tangential-force ramps ({found}): μ_s and μ_d need a ramp "
                             "that slides; " + _RECORD_FORCE)
    mu_s, mu_d = _pool(force_ests)
    beta_s, beta_d = _pool(torsion_ests) if torsion_ests else (_Pooled(math.nan, math.nan),) * 2
    stick, slide, onset_gamma, onset_path, onset_spread, lines = [], [], [], [], [], []
    force_noise, torque_noise = [], []
    beta_s_routes, beta_d_routes = [], []
    for i, rec in enumerate(recs, 1):
        say(f"[{i}/{len(recs)}] {rec.path.name}: load factor per frame")
        series = _gamma_series(rec, mu_s.value, beta_s.value)
        stamps, gamma, source = series.stamps, series.gamma, series.source
        onsets = _onsets_ns(rec)
        at_onset = onset_frames(stamps, gamma, onsets)
        levels = [float(gamma[k]) for k in at_onset]
        sliding = _sliding_mask(rec, stamps)
        wrench = rec.series["ft/wrench"]
        for onset in onsets:
            before = (stamps >= onset - _STICK_WINDOW_NS) & (stamps <= onset - _STICK_GUARD_NS)
            stick.append(frame_noise(gamma[before]))
            w = wrench["usable"].astype(bool) & (wrench["stamp_ns"] >= onset - _STICK_WINDOW_NS) \
                & (wrench["stamp_ns"] <= onset - _STICK_GUARD_NS)
            force_noise.append(float(np.mean([frame_noise(wrench["f_t"][w, i].astype(float)) for i in (0, 1)])))
            torque_noise.append(frame_noise(wrench["tau"][w].astype(float)))
        slide.append(frame_noise(gamma[sliding]))
        if onsets and rec.torsion and source.startswith("exact"):
            before = (stamps >= onsets[0] - _STICK_WINDOW_NS) & (stamps <= onsets[0] - _STICK_GUARD_NS)
            positions = _pad_positions(rec)
            beta_s_routes.append(beta_from_pressure(_pressure_frames(rec, stamps, before), positions, mu_s.value))
            beta_d_routes.append(beta_from_pressure(_pressure_frames(rec, stamps, sliding), positions, mu_d.value))
        onset_gamma += levels
        onset_path += [float(series.path[k]) for k in at_onset]
        onset_spread += [float(series.spread[k]) for k in at_onset]
        lines += [f"== {rec.path}", format_identification(rec.ident),
                  f"load factor {source}: {len(onsets)} gross-slip onsets, γ there "
                  + (", ".join(f"{g:.3f}" for g in levels) or "-")]
    beta_s, beta_d = beta_s.with_route(_median(beta_s_routes)), beta_d.with_route(_median(beta_d_routes))
    reasons = [f"the load factor at a gross-slip onset is {g:.3f}, outside (0, 1.5]: μ_s = {mu_s.value:.4f} does "
               "not fit these recordings (a ramp cut before it slides, or recordings of different contacts)"
               for g in onset_gamma if not 0 < g <= 1.5]
    material = Material(
        name=name, provenance=provenance, mu_s=mu_s.value, mu_s_se=mu_s.se, mu_d=min(mu_d.value, mu_s.value),
        mu_d_se=mu_d.se, beta_s_m=beta_s.value, beta_s_se_m=beta_s.se, beta_d_m=beta_d.value,
        beta_d_se_m=beta_d.se, mu_s_model=mu_s.model, mu_d_model=mu_d.model, beta_s_model_m=beta_s.model,
        beta_d_model_m=beta_d.model, gamma_noise_stick=_median(stick), gamma_noise_slide=_median(slide),
        force_noise_n=_median(force_noise), torque_noise_nm=_median(torque_noise),
        **_onsets_in_range(onset_gamma, onset_path, onset_spread))
    t = detector_thresholds(material)
    lines += [f"material {name} (± standard error, ± model error; the ± 2-sigma interval in % of the value):",
              f"  mu_s   {mu_s.text()}", f"  mu_d   {mu_d.text()}",
              f"  beta_s {beta_s.text(1e3, ' mm')}", f"  beta_d {beta_d.text(1e3, ' mm')}",
              f"  force ramps: {_spread(force_ests, 1.0, '')}",
              *([f"  torque ramps: {_spread(torsion_ests, 1e3, ' mm')}"] if torsion_ests else []),
              f"  F/T noise {material.force_noise_n:.4g} N, {material.torque_noise_nm:.3g} N·m; "
              f"gamma noise stick {material.gamma_noise_stick:.4f}, slide {material.gamma_noise_slide:.4f}; "
              f"detector delta {t.delta:.4f}, gamma_release {t.gamma_release:.4f}, gamma_resume {t.gamma_resume:.4f}"]
    reasons += _implausible(material, {"mu_s": mu_s, "mu_d": mu_d, "beta_s": beta_s, "beta_d": beta_d},
                            force_ests, torsion_ests)
    if reasons:
        raise IdentificationRefused(reasons, material, lines)
    return material, lines


def _onsets_in_range(gammas: list[float], paths: list[float], spreads: list[float]) -> dict[str, tuple[float, ...]]:
    """The onsets whose γ lies in (0, 1.5] (the others are reasons to refuse), as Material fields."""
    keep = [(round(g, 5), round(p, 4), round(k, 4)) for g, p, k in zip(gammas, paths, spreads) if 0 < g <= 1.5]
    return {key: tuple(column) for key, column in zip(("onset_gamma", "onset_path", "onset_spread"), zip(*keep))} \
        if keep else {}


_MAX_LEVEL_SPREAD = 0.1
"""Largest difference of the loadings' sliding levels (dynamic/static) that one contact gives."""


def _implausible(material: Material, values: dict[str, _Pooled], force_ests: list[RampEstimate],
                 torsion_ests: list[RampEstimate]) -> list[str]:
    """Why the material cannot be trusted, each with what to record instead (empty: plausible).

    A coefficient outside its plausible range (lib/material.py); an interval
    (± 2·√(SE² + model²)) as wide as its value; a band δ at its cap (the data
    say the contact can let go at half its capacity); loadings whose sliding levels differ by
    more than :data:`_MAX_LEVEL_SPREAD` (the same contact keeps one sliding level)."""
    reasons = [f"{key} = {getattr(material, key):.4g} lies {why}; " + (_RECORD_TORQUE if key.startswith("beta")
               else _RECORD_FORCE) for key in ("mu_s", "mu_d", "beta_s_m", "beta_d_m")
               if (why := implausible(key, getattr(material, key)))]
    for key, v in values.items():
        record = _RECORD_TORQUE if key.startswith("beta") else _RECORD_FORCE
        half = interval_half_width(v.se, v.model)
        if math.isfinite(v.value) and not half < abs(v.value):
            reasons.append(f"{key} = {v.value:.4g} ± {half:.2g} (2 sigma): the interval is wider than the value; "
                           + record)
    if detector_thresholds(material).delta >= DELTA_MAX:
        reasons.append(f"the detector's band would be its cap, delta = {DELTA_MAX} (sliding level mu_d/mu_s = "
                       f"{material.mu_d / material.mu_s:.3f}, lowest onset load factor "
                       f"{min(material.onset_gamma, default=math.nan):.3f}): no contact lets go at half its capacity; "
                       "a plateau that reaches into an unload or a rest reads so; " + _RECORD_FORCE)
    for ests, record in ((force_ests, _RECORD_FORCE), (torsion_ests, _RECORD_TORQUE)):
        levels = [e.dynamic / e.static for e in ests]
        if len(levels) >= 2 and max(levels) - min(levels) > _MAX_LEVEL_SPREAD:
            reasons.append(f"the loadings' sliding levels (dynamic/static) range {min(levels):.3f}–{max(levels):.3f}, "
                           f"more than {_MAX_LEVEL_SPREAD} apart: not one contact, or a loading that did not slide "
                           "for long; " + record)
    return reasons


def _pad_positions(rec: IdentifiedRecording) -> np.ndarray:
    """Taxel centres (m) of the recording's pad, from its first tactile frame."""
    for m in _tactile_frames(rec.path):
        return PadGeometry(m.rows, m.cols, m.pitch_m).positions
    return np.zeros((0, 2))


def _median(values: list[float]) -> float:
    finite = [v for v in values if math.isfinite(v)]
    return float(np.median(finite)) if finite else math.nan


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("identify", help="a material file (friction, thresholds) from friction-ramp recordings",
                       description="Write a material file (friction coefficients, load-factor noise and onset "
                       "levels, from which the detector's thresholds follow) from friction-ramp recordings at "
                       "constant grip. Pass one tangential-force ramp (fig4a, ident_force) and, for beta, one "
                       "torque ramp (fig4b, ident_torsion); then run the stack with material:=FILE.")
    p.add_argument("recordings", nargs="+", metavar="RECORDING", help=".mcap recordings of friction ramps")
    p.add_argument("-o", "--output", metavar="MATERIAL.toml", required=True,
                   help="the material file to write (an existing one is refused unless --overwrite)")
    p.add_argument("--overwrite", action="store_true", help="replace MATERIAL.toml if it exists")
    p.add_argument("--name", help="material name (default: the output file's stem)")
    p.add_argument("--provenance", default="", help="where the object and the records come from (written to the file)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress line")
    p.add_argument("--force", action="store_true",
                   help="write the file even when the identification is refused (marked as such in the file)")
    p.set_defaults(func=main_identify)


def main_identify(args: argparse.Namespace) -> int:
    """Run ``slipstack identify``; returns the exit code."""
    paths = [Path(r) for r in args.recordings]
    for path in paths:
        if not path.is_file():
            raise RecordingError(f"no recording at {path}")
    out = Path(args.output)
    progress = None if args.quiet else (lambda msg: print(f"\ridentify: {msg:<70}", end="", file=sys.stderr, flush=True))
    stamp = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    provenance = args.provenance or f"slipstack identify {' '.join(p.name for p in paths)} ({stamp})"
    with output_file(out, force=args.overwrite):  # refused before the fit, removed if the fit fails
        try:
            material, lines = identify_material(paths, name=args.name or out.stem, provenance=provenance,
                                                progress=progress)
        except IdentificationRefused as refused:
            if progress is not None:
                print(file=sys.stderr)
            print("\n".join(refused.lines))
            if not args.force:
                raise
            material, lines = replace(refused.material, refused="; ".join(refused.reasons)), []
            print(f"identify: refused, written anyway (--force): {material.refused}", file=sys.stderr)
        if progress is not None and lines:
            print(file=sys.stderr)
        out.write_text(material_toml(material, f"Written by slipstack identify, {stamp}."), encoding="utf-8")
    if lines:
        print("\n".join(lines))
    print(f"wrote {out}; use it with: slipstack launch FILE material:={out}")
    return 0
