"""``slipstack identify RECORDING... -o material.toml``: a material file from Fig. 4 records.

Each recording is one friction ramp at constant ``f_n`` (``slipstack launch fig4a`` /
``fig4b``, or the identification scenes ``ident_force`` / ``ident_torsion``, or the
same on real hardware with ``bag record``). For each, :func:`identify_recording`
(``analysis/report.py``) estimates ``μ_s, μ_d`` (a tangential-force ramp) or
``β_s, β_d`` (a torque ramp), the slip onset taken from the object's slip distance or
angle after the elastic pre-slip when the recording has ``rig/truth``, else from the
ratio's drop. Several recordings of one kind are pooled (inverse-variance mean).

Then the load factor the detector sees, ``γ`` (the exact test of ``lib/limit_set.py``
on each ``tactile/frame`` paired with the nearest ``ft/wrench`` sample, with the
identified ``μ_s``; without tactile frames the ratio over its static value), gives

- ``gamma_noise_stick``: its frame-to-frame noise over the 300 ms before the first
  onset (stopping 20 ms short of it), and ``gamma_noise_slide`` while sliding (from
  100 ms after the onset, only while the truth says gross slip, if it is recorded);
- ``onset_gamma``: γ of the last frame before each gross-slip onset (every
  episode of ``rig/truth``, else the estimate's onset).

Each coefficient has a standard error and, apart from it, a model error
(``lib/identify.py`` step 5, pooled by ``lib/material_fit.pooled_model``); for β the
disagreement with ``μ × r̄`` of the torque ramp's pressure frames
(``lib/material_fit.beta_from_pressure``: β_s with μ_s over the stick window, β_d
with μ_d while sliding) is added to it in quadrature.

``lib/material.py`` turns those into the detector's band and release level. A
recording without ``ft/wrench`` is an error that names it; one without motion truth
falls back to the ratio (said in the output).
"""

from __future__ import annotations

import argparse
import datetime
import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from slipstack.lib.episodes import find_episodes
from slipstack.lib.errors import DecodeError
from slipstack.lib.limit_set import load_factor
from slipstack.lib.material import Material, detector_thresholds, material_toml
from slipstack.lib.output_file import output_file
from slipstack.lib.material_fit import (beta_from_pressure, frame_noise, interval_half_width, onset_levels,
                                         pooled, pooled_model)
from slipstack.lib.pad import PadGeometry
from slipstack.messages import decode
from slipstack.nodes.recording.bag_io import RecordingError, read_recording
from slipstack.analysis.report import Identification, RecordingSeries, format_identification, identify_recording, load_series

__all__ = ["IdentifiedRecording", "identify_material", "add_parser", "main_identify"]

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
        return self.ident.torque_dominates


def _onsets_ns(rec: IdentifiedRecording) -> list[int]:
    series = rec.series
    if series.has("rig/truth"):
        truth = series["rig/truth"]
        return [e.start_ns for e in find_episodes(truth["stamp_ns"], truth["gross_slip"].astype(bool),
                                                  min_gap_ns=_EPISODE_GAP_NS)]
    est = rec.ident.beta if rec.torsion else rec.ident.mu
    if est is None or not math.isfinite(est.onset_t_s):
        return []
    return [series.t0_ns + round(est.onset_t_s * 1e9)]


def _tactile_frames(path: Path) -> list:
    frames = []
    for frame in read_recording(path, ["tactile/frame"]):
        try:
            frames.append(decode(frame.payload))
        except DecodeError:
            continue
    return frames


def _gamma_series(rec: IdentifiedRecording, mu_s: float, beta_s_m: float) -> tuple[np.ndarray, np.ndarray, str]:
    """(stamps ns, γ, source) of the recording: exact on tactile frames, else the F/T ratio."""
    w = rec.series["ft/wrench"]
    ok = w["usable"].astype(bool) & (w["f_n"] > _MIN_F_N)
    ft_ns, f_n, f_t, tau = w["stamp_ns"][ok], w["f_n"][ok].astype(float), w["f_t"][ok].astype(float), w["tau"][ok]
    frames = [m for m in _tactile_frames(rec.path) if m.status == "ok"] if math.isfinite(mu_s) else []
    if frames and ft_ns.size:
        stamps, gammas = [], []
        pad = PadGeometry(frames[0].rows, frames[0].cols, frames[0].pitch_m)
        for m in frames:
            k = int(np.clip(np.searchsorted(ft_ns, m.header.stamp_ns), 1, ft_ns.size - 1))
            k = k if abs(ft_ns[k] - m.header.stamp_ns) < abs(ft_ns[k - 1] - m.header.stamp_ns) else k - 1
            p = np.where(m.dead, 0.0, np.maximum(m.pressure_pa.astype(float), 0.0))
            if p.sum() <= 0 or (m.rows, m.cols) != (pad.rows, pad.cols):
                continue
            r = load_factor(f_n[k] * p / p.sum(), pad.positions, f_t[k], float(tau[k]), mu_s)
            if r.status.usable:
                stamps.append(m.header.stamp_ns)
                gammas.append(r.gamma)
        return np.array(stamps, dtype=np.int64), np.array(gammas), "exact (tactile)"
    if rec.torsion:
        return ft_ns, np.abs(tau) / f_n / beta_s_m, "ratio (F/T only)"
    return ft_ns, np.hypot(f_t[:, 0], f_t[:, 1]) / f_n / mu_s, "ratio (F/T only)"


def _sliding_mask(rec: IdentifiedRecording, stamps_ns: np.ndarray, first_onset_ns: int) -> np.ndarray:
    after = stamps_ns >= first_onset_ns + _SLIDE_SETTLE_NS
    if not rec.series.has("rig/truth"):
        return after
    truth = rec.series["rig/truth"]
    k = np.clip(np.searchsorted(truth["stamp_ns"], stamps_ns), 0, truth["stamp_ns"].size - 1)
    return after & truth["gross_slip"].astype(bool)[k]


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


def _pool(recs: list[IdentifiedRecording], quantity: str) -> tuple[_Pooled, _Pooled]:
    ests = [r.ident.beta if quantity == "beta" else r.ident.mu for r in recs]
    ests = [e for e in ests if e is not None and math.isfinite(e.static)]
    static = pooled([e.static for e in ests], [e.static_se for e in ests])
    dynamic = pooled([e.dynamic for e in ests], [e.dynamic_se for e in ests])
    return (_Pooled(*static, pooled_model([e.static for e in ests], [e.static_model for e in ests])),
            _Pooled(*dynamic, pooled_model([e.dynamic for e in ests], [e.dynamic_model for e in ests])))


def _pressure_frames(rec: IdentifiedRecording, stamps_ns: np.ndarray, keep: np.ndarray) -> list[np.ndarray]:
    """The recording's usable pressure frames whose stamps are in ``stamps_ns[keep]``."""
    wanted = set(stamps_ns[keep].tolist())
    return [np.where(m.dead, 0.0, np.maximum(m.pressure_pa.astype(float), 0.0))
            for m in _tactile_frames(rec.path) if m.status == "ok" and m.header.stamp_ns in wanted]


def identify_material(paths: list[Path], *, name: str, provenance: str = "",
                      progress: Progress | None = None) -> tuple[Material, list[str]]:
    """The material of the recordings and the report lines (one block per recording).

    Raises:
        RecordingError: a recording cannot be read, has no usable ``ft/wrench``,
            none of the recordings is a force ramp (``μ_s`` is needed for the rest), or
            none of the force ramps slides (no onset: no ``μ_s``, ``μ_d``).
    """
    say = progress or (lambda _msg: None)
    recs = []
    for i, path in enumerate(paths, 1):
        say(f"[{i}/{len(paths)}] {path.name}: reading and fitting")
        series = load_series(path).within_scene()
        recs.append(IdentifiedRecording(path, series, identify_recording(series)))
    forces = [r for r in recs if not r.torsion]
    torsions = [r for r in recs if r.torsion]
    if not forces:
        raise RecordingError(f"no tangential-force ramp among {', '.join(p.name for p in paths)}: μ_s is needed "
                             "(record `slipstack launch fig4a` or the ident_force scene and pass it too)")
    if not any(math.isfinite(r.ident.mu.static) and math.isfinite(r.ident.mu.dynamic) for r in forces):
        found = "; ".join(f"{r.path.name}: {r.ident.mu.status.value} ({r.ident.mu.message})" for r in forces)
        raise RecordingError(f"no slip onset in the tangential-force ramps ({found}): μ_s and μ_d need a ramp "
                             "that slides; record one with `slipstack launch scene:=ident_force controller:=false "
                             "recording:=force.mcap` (or fig4a; on hardware pull until the object slides)")
    mu_s, mu_d = _pool(forces, "mu")
    beta_s, beta_d = _pool(torsions, "beta") if torsions else (_Pooled(math.nan, math.nan),) * 2
    stick, slide, onset_gamma, lines = [], [], [], []
    beta_s_routes, beta_d_routes = [], []
    for i, rec in enumerate(recs, 1):
        say(f"[{i}/{len(recs)}] {rec.path.name}: load factor per frame")
        stamps, gamma, source = _gamma_series(rec, mu_s.value, beta_s.value)
        onsets = _onsets_ns(rec)
        levels = onset_levels(stamps, gamma, onsets)
        if onsets:
            first = onsets[0]
            before = (stamps >= first - _STICK_WINDOW_NS) & (stamps <= first - _STICK_GUARD_NS)
            sliding = _sliding_mask(rec, stamps, first)
            stick.append(frame_noise(gamma[before]))
            slide.append(frame_noise(gamma[sliding]))
            if rec.torsion and source.startswith("exact"):
                positions = _pad_positions(rec)
                beta_s_routes.append(beta_from_pressure(_pressure_frames(rec, stamps, before), positions, mu_s.value))
                beta_d_routes.append(beta_from_pressure(_pressure_frames(rec, stamps, sliding), positions,
                                                        mu_d.value))
        onset_gamma += levels
        lines += [f"== {rec.path}", format_identification(rec.ident),
                  f"load factor {source}: {len(onsets)} gross-slip onsets, γ there "
                  + (", ".join(f"{g:.3f}" for g in levels) or "-")]
    beta_s, beta_d = beta_s.with_route(_median(beta_s_routes)), beta_d.with_route(_median(beta_d_routes))
    material = Material(
        name=name, provenance=provenance, mu_s=mu_s.value, mu_s_se=mu_s.se, mu_d=min(mu_d.value, mu_s.value),
        mu_d_se=mu_d.se, beta_s_m=beta_s.value, beta_s_se_m=beta_s.se, beta_d_m=beta_d.value,
        beta_d_se_m=beta_d.se, mu_s_model=mu_s.model, mu_d_model=mu_d.model, beta_s_model_m=beta_s.model,
        beta_d_model_m=beta_d.model, gamma_noise_stick=_median(stick), gamma_noise_slide=_median(slide),
        onset_gamma=tuple(round(g, 5) for g in onset_gamma))
    t = detector_thresholds(material)
    lines += [f"material {name} (± standard error, ± model error; the ± 2-sigma interval in % of the value):",
              f"  mu_s   {mu_s.text()}", f"  mu_d   {mu_d.text()}",
              f"  beta_s {beta_s.text(1e3, ' mm')}", f"  beta_d {beta_d.text(1e3, ' mm')}",
              f"  gamma noise stick {material.gamma_noise_stick:.4f}, slide {material.gamma_noise_slide:.4f}; "
              f"detector delta {t.delta:.4f}, gamma_release {t.gamma_release:.4f}, gamma_resume {t.gamma_resume:.4f}"]
    return material, lines


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
                   help="the material file to write (an existing one is refused unless --force)")
    p.add_argument("--force", action="store_true", help="overwrite MATERIAL.toml if it exists")
    p.add_argument("--name", help="material name (default: the output file's stem)")
    p.add_argument("--provenance", default="", help="where the object and the records come from (written to the file)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress line")
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
    with output_file(out, force=args.force):  # refused before the fit, removed if the fit fails
        material, lines = identify_material(paths, name=args.name or out.stem, provenance=provenance,
                                            progress=progress)
        if progress is not None:
            print(file=sys.stderr)
        out.write_text(material_toml(material, f"Written by slipstack identify, {stamp}."), encoding="utf-8")
    print("\n".join(lines))
    print(f"wrote {out}; use it with: slipstack launch FILE material:={out}")
    return 0
