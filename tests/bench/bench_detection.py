"""Detection measured against the truth, per contact, with one definition (docs/math.md §3.2).

The workflow a user follows, on each of the rig's materials (``lib/rig/scene.py``
RIG_MATERIALS: the rubber, a Coulomb contact with μ_d = μ_s, a strongly weakening one)
and, with ``--engine DIR``, on recordings of a second physics engine (MuJoCo, written by
``tests/bench/mujoco_world.py`` as slipstack recordings):

More in docs/modules.md, `tests/bench/bench_detection.py`.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import sys
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

import slipstack.launch

from slipstack.analysis.identify_cli import IdentificationRefused, identify_material
from slipstack.lib.detection import DetectorConfig
from slipstack.lib.contact_view import pad_positions
from slipstack.lib.detector import NOISE_CAPACITY, ONSET_NS_PER_FRAME
from slipstack.lib.episodes import LEAD_NS, MARGIN_NS, MIN_GAP_NS, RELEASE_NS, detection_quality, find_episodes
from slipstack.lib.limit_set import load_factor, torsional_coefficient
from slipstack.lib.material import NOISE_FLOOR, Material, detector_thresholds, load_material, material_toml
from slipstack.lib.onset_band import PATH_TOLERANCE, SPREAD_TOLERANCE, OnsetBand, load_path, pressure_spread
from slipstack.lib.online_calibration import CalibratedLatch
from slipstack.lib.rig.contact import PressureModel
from slipstack.lib.rig.scene import RIG_MATERIALS, Scene, with_rig_material
from slipstack.launch.launch_file import load_launch_file
from slipstack.launch.lockstep import run_launch_file
from slipstack.nodes.material_param import resolve_material
from slipstack.messages import decode
from slipstack.messages.frame import peek_header
from slipstack.nodes.fusion import Fusion
from slipstack.nodes.recording.bag_io import RecordingWriter, read_recording
from slipstack.nodes.runtime.inprocess import InProcessExecutor
from slipstack.nodes.slip_detector import SlipDetector, SlipDetectorParams
from slipstack.nodes.rig import load_scene_by_name, with_rates
from _versions import code_digest, print_versions

DETECTION_SCENES = ["fig4a", "fig4b", "fig10", "fig11", "fig12", "fig13", "fig14", "fig15", "default"]
IDENT_SCENES = ["ident_force", "ident_torsion", "ident_combined"]
PURE_RAMPS = ["ident_force", "ident_torsion"]
RECORD_MU = 0.45
RECORDED_TOPICS = ["ft/wrench", "tactile/frame", "slip", "rig/truth"]
TACTILE_TESTS = ("exact", "tactile_cor", "tactile_cor_robust", "tactile_cor_known")


PATH_HOLDS = Path(slipstack.launch.__file__).parent / "scenes"
HOLD_KINDS = ("95 % of its path", "95 % of mu_s", "90 % of mu_d")


def holds(material: str) -> dict[str, list[str]]:
    """The material's scenes that must not slip, by kind (:data:`HOLD_KINDS`): at 95 % of the
    load at which their own path lets go (tests/bench/make_path_holds.py), at 95 % of the
    rigid capacity, at 90 % of the sliding friction."""
    paths = [f"hold95path_{path}_{material}" for path in ("force", "torsion", "combined")]
    missing = [name for name in paths if not (PATH_HOLDS / f"{name}.toml").exists()]
    if missing:
        _say(f"left out (not written yet: python tests/bench/make_path_holds.py): {', '.join(missing)}")
        paths = [name for name in paths if name not in missing]
    if material == "coulomb":
        return {HOLD_KINDS[0]: paths, HOLD_KINDS[1]: ["hold_force_coulomb", "hold_torsion_coulomb"], HOLD_KINDS[2]: []}
    return {HOLD_KINDS[0]: paths, HOLD_KINDS[1]: [f"hold95_force_{material}", f"hold95_torsion_{material}"],
            HOLD_KINDS[2]: [f"hold_force_{material}", f"hold_torsion_{material}"]}


def _say(msg: str) -> None:
    print(f"\r  {msg:<72}", end="", file=sys.stderr, flush=True)


def _run(launch: str, scene_file: str, scene: Scene, material: str, args: dict[str, str],
         rates: tuple[float, float]) -> dict:
    """``launch`` in lock-step on the scene ``scene_file`` made of the rig material ``material``,
    controller off, the slip detector at μ = RECORD_MU without online calibration."""
    args = {"scene": scene_file, "rig_material": material, "controller": "false", "calibrate": "off",
            "mu": str(RECORD_MU), "ft_rate_hz": str(rates[0]), "tactile_rate_hz": str(rates[1]),
            "truth_rate_hz": "1000", "monitor": "false", **args}
    t0 = time.monotonic()
    ex = run_launch_file(launch, args, progress=lambda f: _say(f"{scene.name}@{material}: {100 * f:5.1f}%"))
    _say(f"{scene.name}@{material}: {time.monotonic() - t0:.0f} s for {scene.duration_s:g} s simulated\n")
    return ex.published


# -- 1. identification ------------------------------------------------------------------

def true_friction(material: str) -> dict[str, float]:
    """The rig material's μ_s, μ_d and the β_s, β_d of ``ident_torsion``'s contact (m)."""
    mu_s, mu_d = RIG_MATERIALS[material]
    sc = load_scene_by_name("ident_torsion")
    phi = PressureModel(sc.contact, sc.pad, sc.object.pose).phi_uncached(sc.finger.f_initial_N, 0j, 0.0)
    mean_distance = torsional_coefficient(phi, sc.pad.positions, 1.0).beta_m
    return {"mu_s": mu_s, "mu_d": mu_d, "beta_s_m": mu_s * mean_distance, "beta_d_m": mu_d * mean_distance}


def without_truth(path: Path, folder: Path | None = None) -> Path:
    """A copy of the recording without ``rig/truth`` (what hardware records), beside it or in ``folder``."""
    out = (folder or path.parent) / (path.stem + "-no-truth.mcap")
    if not out.exists():
        writer = RecordingWriter(out)
        for frame in read_recording(path):
            if frame.topic != "rig/truth":
                writer.write(frame.topic, frame.payload, frame.log_time_ns)
        writer.close()
    return out


def identify_files(paths: list[Path], name: str, out: Path) -> Material:
    """``slipstack identify`` on ``paths``, written to ``out`` (cached); a refused one is
    written as ``--force`` writes it, its reasons in ``refused``."""
    if not out.exists():
        try:
            found, _lines = identify_material(paths, name=name, progress=_say, provenance=
                                              f"slipstack identify {' '.join(p.name for p in paths)}")
        except IdentificationRefused as refused:
            found = replace(refused.material, refused="; ".join(refused.reasons))
        _say(f"identified {out.name}\n")
        out.write_text(material_toml(found, f"{name}, identified by bench_detection.py."))
    return load_material(out)


def ident_recordings(material: str, cache: Path, rates: tuple[float, float]) -> dict[str, Path]:
    """The identification scenes on ``material``, recorded (cached)."""
    paths = {}
    for name in IDENT_SCENES:
        path = cache / f"{name}@{material}.mcap"
        if not path.exists():
            scene = with_rig_material(load_scene_by_name(name), material)
            recording = {"recording": str(path), "record_topics": f"[{', '.join(RECORDED_TOPICS)}]"}
            _run("stack", name, scene, material, {"method": "exact", "tactile": "true", **recording}, rates)
        paths[name] = path
    return paths


def identification_rows(label: str, truth: dict[str, float], files: dict[str, Material]) -> list[str]:
    """One row per (file, coefficient): truth, identified, ± 2·√(SE² + model²), error."""
    rows = []
    for how, found in files.items():
        for key, scale, unit in (("mu_s", 1, ""), ("mu_d", 1, ""), ("beta_s_m", 1e3, " mm"), ("beta_d_m", 1e3, " mm")):
            stem = key.removesuffix("_m")
            suffix = "_m" if key.endswith("_m") else ""
            value, true = getattr(found, key), truth[key]
            se, model = getattr(found, f"{stem}_se{suffix}"), getattr(found, f"{stem}_model{suffix}")
            half = 2.0 * math.hypot(se, model if math.isfinite(model) else 0.0)
            rows.append(f"| {label} | {how} | {stem} | {true * scale:.4f}{unit} | {value * scale:.4f}{unit} | "
                        f"± {half * scale:.4f}{unit} | {100 * (value / true - 1):+.1f} % |")
        rows.append(f"| {label} | {how} | band δ / γ_release | | {detector_thresholds(found).delta:.3f} / "
                    f"{detector_thresholds(found).gamma_release:.3f} | onsets {len(found.onset_gamma)} | "
                    f"{'refused: ' + found.refused[:60] if found.refused else ''} |")
    return rows


# -- 2. detection -------------------------------------------------------------------------

def true_load_factors(scene: Scene, truth: list) -> np.ndarray:
    """γ of the true load on the true pressure at each truth sample (the contact's μ_s).

    The pressure is the scene's model at the applied normal force and the object's pose;
    the load is the one the contact transmits, at the pad. NaN where no γ.
    """
    positions, mu_s = scene.pad.positions, scene.contact.mu_s
    pressure = PressureModel(scene.contact, scene.pad, scene.object.pose)
    out = np.full(len(truth), np.nan)
    for i, tr in enumerate(truth):
        phi = pressure.phi_uncached(tr.f_n_applied, complex(tr.x, tr.y), tr.theta)
        r = load_factor(phi, positions, tr.load_f_t, tr.load_tau, mu_s)
        if r.status.usable:
            out[i] = r.gamma
    return out


def verdicts(slips: list, contacts: list) -> dict[str, np.ndarray]:
    """Per ``slip`` message: stamp, contact, γ (NaN without a valid verdict), the load it
    judged (f_n N, f_t N, τ N·m), the COR of impending slip (m; NaN if none), and the
    spread of the pressure of the ``contact`` it judged and its pressure-weighted mean
    distance from the geometric median (m; β_s/μ, the torsional capacity per μ f_n), NaN
    without one."""
    ok = [m.status == "ok" for m in slips]
    pressure = {c.header.stamp_ns: _pressure_shape(c) for c in contacts}
    shapes = np.array([pressure.get(m.header.stamp_ns, (math.nan, math.nan)) for m in slips], dtype=float)
    return {"t": np.array([m.header.stamp_ns for m in slips], dtype=np.int64),
            "spread": shapes[:, 0].copy(), "mean_distance": shapes[:, 1].copy(),
            "contact": np.array([m.state != "no-contact" for m in slips], dtype=bool),
            "gamma": np.array([1.0 - m.margin if good else np.nan for m, good in zip(slips, ok)], dtype=float),
            "f_n": np.array([m.f_n for m in slips], dtype=float),
            "f_t": np.array([m.f_t for m in slips], dtype=float).reshape(-1, 2),
            "tau": np.array([m.tau for m in slips], dtype=float),
            "p_c": np.array([m.p_c if m.p_c_valid else (np.nan, np.nan) for m in slips], dtype=float).reshape(-1, 2)}


def _pressure_shape(contact) -> tuple[float, float]:
    """(pressure spread, mean distance m) of a ``contact``'s pressure frame (NaN without one)."""
    if not contact.has_tactile or not contact.phi.size:
        return math.nan, math.nan
    tor = torsional_coefficient(contact.phi, pad_positions(contact.rows, contact.cols, contact.pitch_m), 1.0)
    return pressure_spread(contact.phi), tor.beta_m if tor.status.usable else math.nan


def truth_index(data: dict[str, np.ndarray]) -> np.ndarray:
    """Per verdict frame, the index of the truth sample at or after its stamp (the last one past the end)."""
    return np.clip(np.searchsorted(data["truth_t"], data["t"]), 0, data["truth_t"].size - 1)


def truths(truth: list) -> dict[str, np.ndarray]:
    """Per ``rig/truth`` message: stamp, gross slip, the slip share, the applied f_n (N)."""
    return {"truth_t": np.array([m.header.stamp_ns for m in truth], dtype=np.int64),
            "gross": np.array([m.gross_slip for m in truth], dtype=bool),
            "slip_share": np.array([m.sliding_fraction for m in truth], dtype=float),
            "true_f_n": np.array([m.f_n_applied for m in truth], dtype=float)}


def recorded_scene(scene_file: str, material: str, cache: Path, rates: tuple[float, float]) -> dict[str, np.ndarray]:
    """γ of the launch file's deciding test on every frame at μ = RECORD_MU, and the truth (cached)."""
    path = cache / f"{scene_file}@{material}.npz"
    if path.exists():
        return dict(np.load(path))
    base = scene_file if scene_file in DETECTION_SCENES else "stack"
    args = load_launch_file(base, builtins={"run_dir": "/tmp"}).args
    scene = with_rig_material(with_rates(load_scene_by_name(scene_file), *rates, 1000.0), material)
    tactile = bool(args["tactile"]) and scene.tactile.enabled
    published = _run(base, scene_file, scene, material, {"tactile": str(tactile).lower(), "record": "false"}, rates)
    slips, truth = published["slip"], published["rig/truth"]
    data = {**verdicts(slips, published["contact"]), **truths(truth), "true_gamma": true_load_factors(scene, truth),
            "method": np.array(args["method"])}
    cache.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, **data)
    return data


def flags(data: dict[str, np.ndarray], material: Material, online: bool, record_mu: float = RECORD_MU,
          detector: str = "path") -> np.ndarray:
    """The detector's slip flag on every frame with ``material``'s μ and thresholds
    (``detector``: ``path`` as the node runs: the band of each frame's load path and pressure
    spread, the release when stuck, no verdict below the F/T's noise; ``fixed`` one band,
    no release when stuck, every frame judged: the detector before issue 24's second pass)."""
    thr = detector_thresholds(material)
    stuck = {"sliding_level": thr.sliding_level, "stuck_margin": thr.stuck_margin} if detector == "path" else {}
    config = DetectorConfig(thr.delta, thr.gamma_release, gamma_resume=thr.gamma_resume, onset_ns=ONSET_NS_PER_FRAME,
                            **stuck)
    latch = CalibratedLatch(config, material if online else None)
    margin = 1.0 - data["gamma"] * record_mu / material.mu_s
    if detector == "path" and "mean_distance" in data:
        margin[below_noise(data, material)] = np.nan
    band = OnsetBand.of(material)
    if detector == "path" and band.kinds and "spread" in data:
        deltas = [band.delta(p, k) for p, k in zip(frame_paths(data, material), data["spread"].tolist())]
    else:
        deltas = [None] * margin.size
    return np.array([latch.update(int(t), float(m), in_contact=bool(c), delta=d)[0]
                     for t, m, c, d in zip(data["t"], margin, data["contact"], deltas)])


def frame_paths(data: dict[str, np.ndarray], material: Material) -> list[float]:
    """The load path (``lib/onset_band.load_path``) of every frame's judged load."""
    force = np.hypot(data["f_t"][:, 0], data["f_t"][:, 1])
    return [load_path(f, t, material.mu_s, material.beta_s_m) for f, t in zip(force.tolist(), data["tau"].tolist())]


def below_noise(data: dict[str, np.ndarray], material: Material) -> np.ndarray:
    """The frames the detector does not judge with ``material``'s F/T noise (``lib/detector.py``
    ``below_noise``: μ f_n or the pressure frame's β f_n under 10 times the noise)."""
    f_n = data["f_n"]
    force = material.mu_s * f_n < NOISE_CAPACITY * material.force_noise_n
    torque = material.mu_s * data["mean_distance"] * f_n < NOISE_CAPACITY * material.torque_noise_nm
    return force | torque


@dataclass
class Tally:
    """Sums of one table row over runs."""

    episodes: int = 0
    missed: int = 0
    stick: int = 0
    false: int = 0
    latch: int = 0
    at_or_above_level: int = 0
    just_under_level: int = 0
    with_true_load: bool = False
    by_test: dict[str, list[int]] = field(default_factory=lambda: {"tactile": [0, 0], "ft": [0, 0]})
    delays: list[float] = field(default_factory=list)
    holds_ms: list[float] = field(default_factory=list)
    later_episodes: int = 0
    later_missed: int = 0
    later_delays: list[float] = field(default_factory=list)
    later_false: int = 0
    later_latch: int = 0
    later_stick: int = 0
    hold_scenes: dict[str, list[int]] = field(default_factory=dict)  # kind -> [rises, flagged, frames]

    def add(self, data: dict[str, np.ndarray], f: np.ndarray, period_ns: float, sliding_level: float) -> None:
        q = detection_quality(data["truth_t"], data["gross"], data["t"], f, in_contact=data["contact"])
        k = truth_index(data)
        sticking = data["contact"] & ~data["gross"][k]
        false = f & sticking & ~_excused(data, q)
        if "true_gamma" in data:  # the false alarms outside the latch hold, by the true load against the sliding level
            self.with_true_load = True
            true_gamma = data["true_gamma"][k]
            outside = [_outside_latch(data, f, ~(true_gamma >= level)) for level in
                       (sliding_level, sliding_level - AT_LEVEL)]
            self.at_or_above_level += q.false_alarm_frames - q.latch_hold_frames - outside[0]
            self.just_under_level += outside[0] - outside[1]
        self.episodes += len(q.episodes)
        self.missed += q.missed
        self.stick += q.stick_frames
        self.false += q.false_alarm_frames
        self.latch += q.latch_hold_frames
        kind = "tactile" if str(data["method"]) in TACTILE_TESTS else "ft"
        self.by_test[kind][0] += q.false_alarm_frames
        self.by_test[kind][1] += q.stick_frames
        self.delays += [d / period_ns for d in q.delays_ns]
        self.holds_ms += [h / 1e6 for h in q.holds_ns]
        if len(q.episodes) > 1:  # each run's episodes after its first, and its frames after that one's window
            after = data["t"] > q.episodes[0].end_ns + RELEASE_NS + MARGIN_NS
            later = data["gross"] & (data["truth_t"] > q.episodes[0].end_ns + MIN_GAP_NS)
            ql = detection_quality(data["truth_t"], later, data["t"], f, in_contact=data["contact"])
            self.later_episodes += len(ql.episodes)
            self.later_missed += ql.missed
            self.later_delays += [d / period_ns for d in ql.delays_ns]
            qa = detection_quality(data["truth_t"], data["gross"], data["t"], f, in_contact=data["contact"] & after)
            self.later_false += qa.false_alarm_frames
            self.later_latch += qa.latch_hold_frames
            self.later_stick += qa.stick_frames

    def add_hold(self, kind: str, f: np.ndarray) -> None:
        rises = int(np.count_nonzero(f & ~np.concatenate([[False], f[:-1]])))
        row = self.hold_scenes.setdefault(kind, [0, 0, 0])
        row[0] += rises
        row[1] += int(f.sum())
        row[2] += f.size


def _outside_latch(data: dict[str, np.ndarray], f: np.ndarray, frames: np.ndarray) -> int:
    """The false alarms among ``frames`` outside the latch hold after a true slip (the
    latch hold depends on the flags and episodes alone, not on which frames are counted)."""
    q = detection_quality(data["truth_t"], data["gross"], data["t"], f, in_contact=data["contact"] & frames)
    return q.false_alarm_frames - q.latch_hold_frames


def _excused(data: dict[str, np.ndarray], q) -> np.ndarray:
    """The frames inside some episode's window [onset − 20 ms, end + 25 ms]."""
    t, out = data["t"], np.zeros(data["t"].shape, dtype=bool)
    for ep in q.episodes:
        out |= (t >= ep.start_ns - LEAD_NS) & (t <= ep.end_ns + RELEASE_NS + MARGIN_NS)
    return out


def _pct(values: list[float], q: float, fmt: str = "{:+.1f}") -> str:
    return fmt.format(float(np.percentile(values, q))) if values else "-"


def _share(part: int, whole: int) -> str:
    return f"{100 * part / max(whole, 1):.2f} %"


AT_LEVEL = 0.02
"""A true load within this under the contact's sliding level is reported apart: there the
measured γ (noise about 0.006 on the rig) hardly tells a stuck contact from a sliding one."""


def detection_row(label: str, material: Material, t: Tally, online: bool) -> str:
    thr = detector_thresholds(material)
    rest = t.false - t.latch - t.at_or_above_level
    holds_text = " / ".join(f"{r[0]} ({100 * r[1] / max(r[2], 1):.1f} %)" if r[2] else "-"
                            for r in (t.hold_scenes.get(kind, [0, 0, 0]) for kind in HOLD_KINDS))
    later = (f"{t.later_missed} of {t.later_episodes}, {_pct(t.later_delays, 95)}, "
             f"{_share(t.later_false, t.later_stick)} ({_share(t.later_latch, t.later_stick)})" if online else "")
    return (f"| {label} | {thr.delta:.3f} / {thr.gamma_release:.3f} | {t.episodes} | {t.missed} | "
            f"{_pct(t.delays, 50)} / {_pct(t.delays, 95)} | {_share(t.false, t.stick)} ({_share(t.latch, t.stick)}; "
            + (f"{_share(t.at_or_above_level, t.stick)}; {_share(rest, t.stick)}, of which "
               f"{_share(t.just_under_level, t.stick)}) | " if t.with_true_load else "-; -) | ") +
            f"{_share(*t.by_test['tactile'])} / {_share(*t.by_test['ft'])} | "
            f"{_pct(t.holds_ms, 50, '{:.0f}')} / {_pct(t.holds_ms, 95, '{:.0f}')} | {holds_text} | {later} |")


DETECTION_HEADER = [
    "| contact, material file, detector | δ / γ_release | episodes | missed | delay p50 / p95 (samples) | false alarms "
    "((a) latch hold after a true slip; (b) stuck, true load at or above the true sliding level μ_d/μ_s; (c) the "
    "rest, of which within 0.02 under that level) | false alarms: tactile / F/T tests | latch hold "
    "p50 / p95 ms | holds at 95 % of their path / 95 % of μ_s / 90 % of μ_d: alarms (flagged) | online, each run "
    "after its first episode: missed, delay p95, false alarms ((a) the latch hold after a true slip) |",
    "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
]


def evaluate(runs: dict[str, dict], hold_kinds: dict[str, str], material: Material, online: bool,
             period_ns: float, sliding_level: float, record_mu: float = RECORD_MU, detector: str = "path") -> Tally:
    """Every run with ``material`` and ``detector`` (:func:`flags`; ``hold_kinds``: scene →
    its kind of hold, for the holds; ``sliding_level``: the contact's true μ_d/μ_s)."""
    tally = Tally()
    for scene, data in runs.items():
        f = flags(data, material, online, record_mu, detector)
        if scene in hold_kinds:
            tally.add_hold(hold_kinds[scene], f)
        tally.add(data, f, period_ns, sliding_level)
    return tally


# -- 3. where the false alarms at the sliding level come from (--explain) ---------------

def path_name(path: float) -> str:
    """A load path in words: force (p < 0.15), torque (p > 0.85), combined, none (no load)."""
    return "none" if math.isnan(path) else "force" if path < 0.15 else "torque" if path > 0.85 else "combined"


def band_source(band: OnsetBand, path: float, spread: float) -> str:
    """Which band ``lib/onset_band.py`` gives a load of this path and spread, in words."""
    kind = band.kind_of(path, spread)
    if math.isnan(path):
        return "no load path: all onsets"
    if kind is None:
        return "no onset of its kind"
    return f"its kind (path {kind.path:.2f}, spread {kind.spread:.2f}; {kind.count} onsets)"


def scene_onsets(data: dict[str, np.ndarray], material: Material) -> list[tuple[float, float, float]]:
    """(measured γ, load path, pressure spread) of the last frame before each true episode,
    as ``identify`` keeps an onset."""
    gamma = data["gamma"] * RECORD_MU / material.mu_s
    paths = frame_paths(data, material)
    out = []
    for ep in find_episodes(data["truth_t"], data["gross"], min_gap_ns=MIN_GAP_NS):
        i = int(np.searchsorted(data["t"], ep.start_ns)) - 1
        if i >= 0 and 0.0 < gamma[i] and math.isfinite(gamma[i]) and math.isfinite(paths[i]):
            out.append((min(float(gamma[i]), 1.5), paths[i], float(data["spread"][i])))
    return out


def explain(runs: dict[str, dict], hold_kinds: dict[str, str], material: Material, level: float,
            label: str, period_ns: float) -> tuple[list[str], list[str], str, str]:
    """The (b) false alarms (stuck, true load at or above ``level``) by the load their flag
    rose on: its path, the band it got and that band's edge, beside the onsets the scenes
    themselves show on that path; then the detector with those onsets in the file, and the
    bounds of :func:`own_onset_bound` and :func:`oracle_row`."""
    band = OnsetBand.of(material)
    parts: dict[tuple[str, str], dict] = {}
    stick = 0
    seen: dict[str, list[float]] = {}
    onsets = {scene: scene_onsets(data, material) for scene, data in runs.items()}
    for scene, data in runs.items():
        f = flags(data, material, False)
        k = truth_index(data)
        at_level = data["true_gamma"][k] >= level
        stick += int(np.count_nonzero(data["contact"] & ~data["gross"][k]))
        paths, index = frame_paths(data, material), np.arange(f.size)
        rose_at = np.maximum.accumulate(np.where(f & ~np.concatenate([[False], f[:-1]]), index, 0))
        for r in np.unique(rose_at[f]):
            spread = float(data["spread"][r])
            frames = _outside_latch(data, f, (rose_at == r) & at_level)
            if frames:
                part = parts.setdefault((path_name(paths[r]), band_source(band, paths[r], spread)),
                                        {"frames": 0, "scenes": {}, "edges": set()})
                part["frames"] += frames
                part["scenes"][scene] = part["scenes"].get(scene, 0) + frames
                part["edges"].add(round(1.0 - (band.delta(paths[r], spread) if band.kinds else band.lowest), 3))
        for g, p, _ in onsets[scene]:
            seen.setdefault(path_name(p), []).append(g)
    rows = []
    for (path, source), part in sorted(parts.items(), key=lambda x: -x[1]["frames"]):
        kind_onsets = [g for g, p, k in zip(material.onset_gamma, material.onset_path or (), material.onset_spread or ())
                       if band.kind_of(p, k) is not None and band_source(band, p, k) == source]
        shown = seen.get(path, [])
        scenes = ", ".join(f"{s} {100 * n / stick:.2f}" for s, n in sorted(part["scenes"].items(), key=lambda x: -x[1]))
        rows.append(f"| {label} | {path} | {source} | {_share(part['frames'], stick)} | {scenes} | "
                    f"{' / '.join(f'{e:.3f}' for e in sorted(part['edges']))} | "
                    f"{', '.join(f'{g:.3f}' for g in kind_onsets) or '-'} | "
                    f"{f'{min(shown):.3f}–{max(shown):.3f} ({len(shown)})' if shown else '-'} |")
    tallies = []
    for how, extra in (("+ every scene's own onsets", lambda s: [o for v in onsets.values() for o in v]),
                       ("+ the other scenes' onsets", lambda s: [o for t, v in onsets.items() if t != s for o in v])):
        tally = Tally()
        for scene, data in runs.items():
            more = extra(scene)
            covered = replace(material, onset_gamma=(*material.onset_gamma, *[o[0] for o in more]),
                              onset_path=(*material.onset_path, *[o[1] for o in more]),
                              onset_spread=(*material.onset_spread, *[o[2] for o in more]))
            f = flags(data, covered, False)
            if scene in hold_kinds:
                tally.add_hold(hold_kinds[scene], f)
            tally.add(data, f, period_ns, level)
        tallies.append(detection_row(f"{label}, its file {how}", material, tally, False))
    return rows, tallies, own_onset_bound(runs, onsets, material, level), oracle_row(runs, onsets, material)


def stick_sigma(material: Material) -> float:
    """The γ noise of a stuck contact the oracle thresholds stand 3σ under an onset by: the
    material's, at least lib/material.py's NOISE_FLOOR."""
    return max(material.gamma_noise_stick, NOISE_FLOOR)


def own_onset_bound(runs: dict[str, dict], onsets: dict[str, list], material: Material, level: float) -> str:
    """Stuck frames outside every window at or above the edge of each scene's own lowest
    measured onset less 3σ (a threshold per scene that knows where that scene lets go), by
    the true load against ``level``: what no γ threshold that catches the onsets avoids."""
    sigma = stick_sigma(material)
    stick = above = under = 0
    for scene, data in runs.items():
        k = truth_index(data)
        sticking = data["contact"] & ~data["gross"][k]
        stick += int(np.count_nonzero(sticking))
        if not onsets[scene]:
            continue
        q = detection_quality(data["truth_t"], data["gross"], data["t"], np.zeros(data["t"].size, dtype=bool))
        edge = min(g for g, _, _ in onsets[scene]) - 3.0 * sigma
        over = sticking & ~_excused(data, q) & (data["gamma"] * RECORD_MU / material.mu_s >= edge)
        at_level = data["true_gamma"][k] >= level
        above += int(np.count_nonzero(over & at_level))
        under += int(np.count_nonzero(over & ~at_level))
    return (f"| {material.name} | {_share(above, stick)} | {_share(under, stick)} |")


def above_own_onsets(data: dict[str, np.ndarray], onsets: list[tuple[float, float, float]], material: Material,
                     by_kind: bool) -> tuple[int, int]:
    """Sticking frames outside every episode's window at or above the run's own lowest measured
    onset less 3σ (``by_kind``: the lowest of its onsets of the frame's kind, path within
    PATH_TOLERANCE and spread within SPREAD_TOLERANCE of it, lib/onset_band.py), split by the
    truth (no sliding, partial slip): what an oracle threshold that knows where this very run
    lets go, per load kind or not, cannot avoid flagging."""
    if not onsets:
        return 0, 0
    sigma = stick_sigma(material)
    k = truth_index(data)
    q = detection_quality(data["truth_t"], data["gross"], data["t"], np.zeros(data["t"].size, dtype=bool))
    stuck = data["contact"] & ~data["gross"][k] & ~_excused(data, q)
    gamma = data["gamma"] * RECORD_MU / material.mu_s
    paths, spread = np.array(frame_paths(data, material)), data["spread"]
    above = np.zeros(gamma.size, dtype=bool)
    for level, path, onset_spread in onsets:
        same = np.ones(gamma.size, dtype=bool)
        if by_kind:
            same = np.abs(paths - path) <= PATH_TOLERANCE
            same &= np.isnan(spread) if math.isnan(onset_spread) else np.abs(spread - onset_spread) <= SPREAD_TOLERANCE
        above |= same & (gamma >= level - 3.0 * sigma)
    none = data["slip_share"][k] <= NO_SLIDING
    return int(np.count_nonzero(stuck & above & none)), int(np.count_nonzero(stuck & above & ~none))


def oracle_row(runs: dict[str, dict], onsets: dict[str, list], material: Material) -> str:
    """:func:`above_own_onsets` over every run, per run and per run and load kind, as shares of
    all sticking frames."""
    stick = sum(int(np.count_nonzero(d["contact"] & ~d["gross"][truth_index(d)])) for d in runs.values())
    cells = []
    for by_kind in (False, True):
        none, partial = np.sum([above_own_onsets(d, onsets[s], material, by_kind) for s, d in runs.items()], axis=0)
        cells += [_share(int(none + partial), stick), _share(int(none), stick), _share(int(partial), stick)]
    return f"| {material.name} | {' | '.join(cells)} |"


FOLLOW_NS = 500_000_000
"""How soon a true gross slip must follow a frame for the frame to count as followed by one."""


def followed_by_slip(data: dict[str, np.ndarray], f: np.ndarray) -> np.ndarray:
    """Counts over the sticking frames outside every episode's window (``lib/episodes``):
    (flagged, and of those a true gross-slip onset follows within FOLLOW_NS; all, and of those
    followed) for frames in true partial slip, then the same for frames with no true sliding."""
    k = truth_index(data)
    q = detection_quality(data["truth_t"], data["gross"], data["t"], f, in_contact=data["contact"])
    stuck = data["contact"] & ~data["gross"][k] & ~_excused(data, q)
    onsets = np.array([ep.start_ns for ep in q.episodes], dtype=np.int64)
    after = np.searchsorted(onsets, data["t"], side="right")
    soon = np.zeros(f.size, dtype=bool)
    has_next = after < onsets.size
    soon[has_next] = onsets[after[has_next]] - data["t"][has_next] <= FOLLOW_NS
    none = data["slip_share"][k] <= NO_SLIDING
    out = []
    for state in (~none, none):
        for frames in (stuck & state & f, stuck & state):
            out += [int(np.count_nonzero(frames)), int(np.count_nonzero(frames & soon))]
    return np.array(out)


def follow_row(runs: dict[str, dict], material: Material) -> str:
    """:func:`followed_by_slip` over every run with ``material``'s own file (path band, calibrate off)."""
    c = np.sum([followed_by_slip(d, flags(d, material, False)) for d in runs.values()], axis=0)
    return (f"| {material.name} | {_share(c[1], c[0])} of {c[0]} | {_share(c[3], c[2])} of {c[2]} | "
            f"{_share(c[5], c[4])} of {c[4]} | {_share(c[7], c[6])} of {c[6]} |")


FOLLOW_HEADER = [
    "| contact | flagged, true partial slip | all, true partial slip | flagged, no true sliding | "
    "all, no true sliding |", "| --- | ---: | ---: | ---: | ---: |"]


ORACLE_HEADER = [
    "| contact | per run: all | no true sliding | true partial slip | per run and load kind: all | no true sliding | "
    "true partial slip |", "| --- | ---: | ---: | ---: | ---: | ---: | ---: |"]


NO_SLIDING = 1e-9
"""A truth ``sliding_fraction`` at or under this is no sliding at all (the rig writes 0.0
exactly when every taxel sticks; under 0.1 % of its sticking frames lie in (1e-9, 1e-3])."""


def by_truth_state(data: dict[str, np.ndarray], f: np.ndarray) -> tuple[int, int, int, int]:
    """False alarms (``lib/episodes`` ``detection_quality``) and sticking frames, each split by
    the truth's state at the frame: (false, no sliding; false, partial slip; sticking, no
    sliding; sticking, partial slip). No sliding: ``sliding_fraction`` ≤ NO_SLIDING; partial
    slip: above it, not gross."""
    k = truth_index(data)
    none = data["slip_share"][k] <= NO_SLIDING
    q = [detection_quality(data["truth_t"], data["gross"], data["t"], f, in_contact=data["contact"] & frames)
         for frames in (none, ~none)]
    return q[0].false_alarm_frames, q[1].false_alarm_frames, q[0].stick_frames, q[1].stick_frames


def truth_state_row(runs: dict[str, dict], material: Material, label: str) -> str:
    """One row of the split of :func:`by_truth_state` over every run, ``material``'s file,
    path band, calibrate off."""
    fn, fp, sn, sp = np.sum([by_truth_state(data, flags(data, material, False)) for data in runs.values()], axis=0)
    stick = sn + sp
    return (f"| {label} | {_share(fn + fp, stick)} ({fn + fp}) | {_share(fn, stick)} ({fn}) | "
            f"{_share(fp, stick)} ({fp}) | {_share(sp, stick)} ({sp} of {stick}) |")


TRUTH_STATE_HEADER = [
    "| contact | false alarms (frames) | on frames with no true sliding | on frames of true partial slip | "
    "sticking frames in partial slip |",
    "| --- | ---: | ---: | ---: | ---: |"]


EXPLAIN_HEADER = [
    "| contact | path the flag rose on | its band | (b) share | scenes (points) | band edge used | identified "
    "onsets of that kind | measured onsets the scenes show on that path: min–max (count) |",
    "| --- | --- | --- | ---: | --- | ---: | --- | --- |"]


# -- 4. the second engine ---------------------------------------------------------------

def engine_run(path: Path, cache: Path) -> dict[str, np.ndarray]:
    """γ of the exact test on every frame of an engine recording, through the real fusion and
    slip_detector nodes (μ = RECORD_MU, calibrate off), and its truth (cached)."""
    out = cache / f"engine-{path.stem}.npz"
    if out.exists():
        return dict(np.load(out))
    frames = list(read_recording(path, ["ft/wrench", "tactile/frame", "rig/truth"]))
    events = [(head.stamp_ns, f.topic, f.payload) for f in frames if f.topic != "rig/truth"
              for head in [peek_header(f.payload)] if head is not None]
    ex = InProcessExecutor([Fusion(), SlipDetector(SlipDetectorParams(mu=RECORD_MU))],
                           start_ns=min(t for t, _, _ in events))
    ex.feed(events)
    ex.run()
    ex.stop()
    truth = [decode(f.payload) for f in frames if f.topic == "rig/truth"]
    data = {**verdicts(ex.published["slip"], ex.published["contact"]), **truths(truth), "method": np.array("exact")}
    np.savez_compressed(out, **data)
    return data


def engine_tables(folder: Path, cache: Path, default: Material, period_ns: float, explain: bool) -> list[str]:
    """The identification and detection tables on the engine's recordings (one block per μ;
    ``explain``: also the false alarms by the truth's slip state, :func:`truth_state_row`)."""
    cache.mkdir(parents=True, exist_ok=True)
    scenarios = {p: json.loads(p.with_suffix(".json").read_text())["scenario"] for p in sorted(folder.glob("*.mcap"))
                 if p.with_suffix(".json").exists()}
    ident_rows, det_rows, state_rows = [], [], []
    for mu in sorted({sc["mu"] for sc in scenarios.values()}):
        tag = f"engine μ {mu:g}"
        own = {p: sc for p, sc in scenarios.items() if sc["mu"] == mu}
        ident = [p for p, sc in own.items() if sc["name"].startswith(("force_flat", "torque_flat"))]
        if len(ident) < 2:
            continue
        uniform = np.ones(256)
        r_mean = torsional_coefficient(uniform, load_scene_by_name("ident_force").pad.positions, 1.0).beta_m
        truth = {"mu_s": mu, "mu_d": mu, "beta_s_m": mu * r_mean, "beta_d_m": mu * r_mean}
        files = {"identified (truth)": identify_files(ident, tag, cache / f"engine-material-{mu:g}.toml"),
                 "identified (no truth)": identify_files([without_truth(p, cache) for p in ident], tag,
                                                         cache / f"engine-material-{mu:g}-no-truth.toml")}
        ident_rows += identification_rows(tag, truth, files)
        runs = {p.stem: engine_run(p, cache) for p in own if p not in ident}
        hold_kinds = {p.stem: HOLD_KINDS[1] if sc["name"].startswith("hold95") else HOLD_KINDS[2]
                      for p, sc in own.items() if not sc["expect_slip"]}
        for label, material, online, detector in (
                (f"{tag}, fixed band", files["identified (truth)"], False, "fixed"),
                (f"{tag}, path band", files["identified (truth)"], False, "path"),
                (f"{tag}, **no file**, calibrate off", default, False, "path"),
                (f"{tag}, **no file**, calibrate online", default, True, "path")):
            det_rows.append(detection_row(label, material, evaluate(runs, hold_kinds, material, online, period_ns,
                                                                    1.0, detector=detector), online))
        state_rows.append(truth_state_row(runs, files["identified (truth)"], tag))
    state = ["", "The same split of the false alarms by the truth's state (the engine's sliding_fraction: the share "
             "of Σ φ|u| on contacts at the friction cone, tests/bench/engine_mujoco.py):", "",
             *TRUTH_STATE_HEADER, *state_rows] if explain else []
    return (["", f"Second engine ({folder}): identification from its force_flat and torque_flat sessions (press, "
             "twice: ramp past slip, hold, unload, rest; β truth: μ × the mean taxel distance of a uniform pressure):", "",
             "| contact | file | quantity | truth | identified | ± 2 sigma | error |",
             "| --- | --- | --- | ---: | ---: | ---: | ---: |", *ident_rows, "",
             "Detection on every other recording (force, torque, combined, pivot ramps on flat, curved, tilted pads, "
             "grip steps; holds: "
             "hold95_* under '95 %', the rest of the never-slipping ones under the second column):", "",
             *DETECTION_HEADER, *det_rows, *state])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--materials", nargs="+", default=list(RIG_MATERIALS), choices=list(RIG_MATERIALS),
                    help="rig materials (default: all)")
    ap.add_argument("--scenes", nargs="+", default=DETECTION_SCENES, help="detection scenes (default: all shipped)")
    ap.add_argument("--ft-rate", type=float, default=500.0, help="F/T rate (Hz), default the stack's 500")
    ap.add_argument("--tactile-rate", type=float, default=250.0, help="tactile rate (Hz), default 250")
    ap.add_argument("--cache", type=Path, default=Path("/tmp/slipstack-bench-detection"),
                    help="recordings, material files and per-scene runs, in a folder named by the code's "
                         "digest and the rates (other code, scenes or rates: a new folder)")
    ap.add_argument("--engine", type=Path, help="a folder of the second engine's recordings "
                    "(tests/bench/engine_mujoco.py writes them, a .json beside each)")
    ap.add_argument("--explain", action="store_true", help="also: the (b) false alarms by the load their flag "
                    "rose on and the band it got, the detector with the scenes' own onsets in the file, and "
                    "all its false alarms by the truth's slip state (none / partial) at the flagged frame")
    args = ap.parse_args()
    print_versions()
    rates = (args.ft_rate, args.tactile_rate)
    args.cache = args.cache / f"{code_digest()}-{rates[0]:g}-{rates[1]:g}"
    args.cache.mkdir(parents=True, exist_ok=True)
    period_ns = 1e9 / args.ft_rate
    t0 = time.monotonic()
    default = resolve_material("")
    ident_rows, det_rows, why_rows, covered_rows, bound_rows = [], [], [], [], []
    state_rows, oracle_rows, follow_rows = [], [], []
    for m in args.materials:
        paths = ident_recordings(m, args.cache, rates)
        every = [paths[n] for n in IDENT_SCENES]
        files = {"identified (truth)": identify_files(every, m, args.cache / f"material-{m}.toml"),
                 "identified (no truth)": identify_files([without_truth(p) for p in every], m,
                                                         args.cache / f"material-{m}-no-truth.toml"),
                 "pure ramps (truth)": identify_files([paths[n] for n in PURE_RAMPS], m,
                                                      args.cache / f"material-{m}-pure.toml")}
        ident_rows += identification_rows(m, true_friction(m), files)
        hold_kinds = {s: kind for kind, scenes in holds(m).items() for s in scenes}
        runs = {s: recorded_scene(s, m, args.cache, rates) for s in [*args.scenes, *hold_kinds]}
        for label, material, online, detector in (
                (f"{m}, fixed band", files["identified (truth)"], False, "fixed"),
                (f"{m}, path band", files["identified (truth)"], False, "path"),
                (f"{m}, its file from the pure ramps, path band", files["pure ramps (truth)"], False, "path"),
                (f"{m}, path band, calibrate online", files["identified (truth)"], True, "path"),
                (f"{m}, **no file**, calibrate off", default, False, "path"),
                (f"{m}, **no file**, calibrate online", default, True, "path")):
            level = RIG_MATERIALS[m][1] / RIG_MATERIALS[m][0]
            det_rows.append(detection_row(label, material, evaluate(runs, hold_kinds, material, online, period_ns,
                                                                    level, detector=detector), online))
        if args.explain:
            rows, tallies, bound, oracle = explain(runs, hold_kinds, files["identified (truth)"], level, m,
                                                   period_ns)
            oracle_rows.append(oracle)
            why_rows += rows
            covered_rows += tallies
            bound_rows.append(bound)
            state_rows.append(truth_state_row(runs, files["identified (truth)"], m))
            follow_rows.append(follow_row(runs, files["identified (truth)"]))
    print(f"\nwall time {time.monotonic() - t0:.0f} s (cache {args.cache})\n")
    print("Identification (ident_force, ident_torsion, ident_combined as a user records them; lock-step, F/T "
          f"{args.ft_rate:g} Hz, tactile {args.tactile_rate:g} Hz; ± 2·√(SE² + model²)):\n")
    print("| contact | file | quantity | truth | identified | ± 2 sigma | error |\n| --- | --- | --- | ---: | ---: | ---: | ---: |")
    print("\n".join(ident_rows))
    print(f"\nDetection, controller off, scenes: {', '.join(args.scenes)} and the holds; F/T period "
          f"{period_ns / 1e6:g} ms\n")
    print("\n".join(DETECTION_HEADER + det_rows))
    if args.explain:
        print("\nThe (b) false alarms (stuck, true load at or above the true μ_d/μ_s) of each contact's own file, "
              "by the load their flag rose on (shares of all sticking frames):\n")
        print("\n".join(EXPLAIN_HEADER + why_rows))
        print("\nThe same file with the measured onsets of the detection scenes added (every scene's, and all but "
              "the scene judged): what covering every path the scenes use would give (a bound, not a recipe):\n")
        print("\n".join(DETECTION_HEADER + covered_rows))
        print("\nStuck frames outside the windows at or above each scene's own lowest measured onset less 3σ "
              "(a threshold per scene; what catching every onset costs any γ threshold):\n")
        print("\n".join(["| contact | true load at or above μ_d/μ_s | under it |", "| --- | ---: | ---: |",
                         *bound_rows]))
        print("\nThe false alarms of each contact's own file (path band, calibrate off) by the truth's state at the "
              f"flagged frame: no sliding (rig/truth sliding_fraction ≤ {NO_SLIDING:g}) or partial slip (above it, "
              "not gross); and the share of all sticking frames in partial slip (shares of all sticking frames):\n")
        print("\n".join(TRUTH_STATE_HEADER + state_rows))
        print(f"\nSticking frames outside the windows that a true gross slip follows within {FOLLOW_NS / 1e9:g} s, "
              "flagged by each contact's own file and all, by the truth's state: are the flags warnings?\n")
        print("\n".join(FOLLOW_HEADER + follow_rows))
        print("\nStuck frames outside the windows at or above the run's own lowest measured onset less 3σ, per run and "
              "per run and load kind (path within 0.15, pressure spread within 0.1): an oracle threshold that knows "
              "where each run lets go on each load kind, by the truth's state (shares of all sticking frames):\n")
        print("\n".join(ORACLE_HEADER + oracle_rows))
    if args.engine is not None:
        folder = hashlib.sha256(str(args.engine.resolve()).encode()).hexdigest()[:8]
        print("\n".join(engine_tables(args.engine, args.cache / f"engine-{folder}", default, period_ns, args.explain)))


if __name__ == "__main__":
    main()
