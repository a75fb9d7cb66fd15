"""Detection measured against the truth, per contact material.

The workflow a user follows, on each of the rig's materials (``lib/rig/scene.py``
RIG_MATERIALS: the rubber, a Coulomb contact with μ_d = μ_s, a strongly weakening one):

1. **Identify**: the identification scenes ``ident_force`` and ``ident_torsion`` on
   that material run in lock-step (controller off) and are recorded to MCAP;
   ``slipstack identify`` (:func:`slipstack.analysis.identify_cli.identify_material`)
   turns them into a material file. The first table compares it with the scene's truth
   (μ from the material; β = μ × the pressure-weighted mean taxel distance about the
   geometric median of the scene's true pressure at 5 N); intervals are ± 2 standard errors.
2. **Detect**: every detection scene (the paper scenes fig4a–fig15 and ``default``) and
   the material's negative scenes (``hold_force_<material>``, ``hold_torsion_<material>``,
   which must not slip) run on that material with the controller off and the deciding
   test of the scene's launch file. The load factor γ of every frame is recorded once
   (with μ = 0.45; the F/T-only tests with the launch file's β); γ of all these tests is
   inversely proportional to μ (β scaling with μ, as a contact's β does), so a material
   file's μ_s gives ``γ·0.45/μ_s``, and its band δ and release level (``lib/material.py``)
   drive the detector's latch (``lib/detection.py``) over those frames.

Metrics per material (the true load factor is the rig's true load on its true pressure,
with the contact's μ_s; the F/T period is 2 ms at the default 500 Hz):

- *missed*: true gross-slip episodes with no flag from 100 ms before their onset to
  50 ms after their end (``lib/episodes.py``);
- *delay*: first flag minus true onset, in F/T periods, p50 / p95 (negative: before);
- *false alarms*: frames flagged by the band itself (margin ≤ δ, not merely held by
  the latch) while the truth says stick and the true load factor is below the band by
  more than the material's noise (γ_true < 1 − δ − σ_stick), in % of the sticking
  frames (truth not in gross slip); *raised* counts the flag's rising edges among them;
  then the same split by the deciding test: the scenes a tactile test decides, and the
  F/T-only fig10–12, whose tests carry their own model error (the linear limit surface
  of fig11/12 over-predicts γ on combined loads, by up to 0.3);
- *latch hold*: for each episode, how long the flag stays up after the true slip ended
  (until the next episode at most; p50 / p95 ms over all episodes), split by whether the
  true load factor fell below the material's release level by more than its sliding
  noise during the hold (*could release*: the detector could have let go; timed from that
  moment, so it is the detector's own lag: the release dwell and the frames the noise
  keeps above the level) or did not, staying between the release
  level and the sliding level μ_d/μ_s or higher (*cannot tell*: force data cannot tell
  such a load from sliding; timed from the slip's end); counts in brackets;
- *negative*: flag rising edges and flagged frames in the negative scenes.

The second part repeats the detection table with the wrong material file (the rubber's
on the Coulomb contact, the Coulomb's on the rubber): what a missing identification costs.

    python tests/bench/bench_detection.py                        # all materials and scenes
    python tests/bench/bench_detection.py --materials coulomb --scenes fig15 default
    python tests/bench/bench_detection.py --cache /tmp/slipstack-bench-detection   # reuse runs
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from slipstack.lib.detection import DetectorConfig, SlipLatch
from slipstack.lib.episodes import find_episodes
from slipstack.lib.limit_set import load_factor, torsional_coefficient
from slipstack.lib.material import Material, detector_thresholds, load_material, material_toml
from slipstack.lib.material_fit import interval_half_width
from slipstack.lib.rig.contact import PressureModel
from slipstack.lib.rig.scene import RIG_MATERIALS, Scene, with_rig_material
from slipstack.launch.launch_file import load_launch_file
from slipstack.analysis.identify_cli import identify_material
from slipstack.launch.lockstep import run_launch_file
from slipstack.nodes.rig import load_scene_by_name, with_rates
from _versions import print_versions

DETECTION_SCENES = ["fig4a", "fig4b", "fig10", "fig11", "fig12", "fig13", "fig14", "fig15", "default"]
NEGATIVE_SCENES = ["hold_force", "hold_torsion"]
IDENT_SCENES = ["ident_force", "ident_torsion"]
WRONG_FILES = [("coulomb", "rubber"), ("rubber", "coulomb")]  # (contact, material file)
RECORD_MU = 0.45
LEAD_NS, GRACE_NS, GAP_NS = 100_000_000, 50_000_000, 20_000_000
RECORDED_TOPICS = ["ft/wrench", "tactile/frame", "slip", "rig/truth"]
TACTILE_TESTS = ("exact", "tactile_cor", "tactile_cor_robust")


def _say(msg: str) -> None:
    print(f"\r  {msg:<72}", end="", file=sys.stderr, flush=True)


def _run(launch: str, scene_file: str, scene: Scene, material: str, args: dict[str, str],
         rates: tuple[float, float]) -> dict:
    """``launch`` in lock-step on the shipped scene ``scene_file`` (``scene``, for the progress lines)
    made of the rig material ``material``, controller off, the slip detector at μ = RECORD_MU;
    the published messages."""
    args = {"scene": scene_file, "rig_material": material, "controller": "false",
            "mu": str(RECORD_MU), "ft_rate_hz": str(rates[0]), "tactile_rate_hz": str(rates[1]),
            "truth_rate_hz": "1000", "monitor": "false", **args}
    t0 = time.monotonic()
    ex = run_launch_file(launch, args, progress=lambda f: _say(f"{scene.name}: {100 * f:5.1f}%"))
    _say(f"{scene.name}: {time.monotonic() - t0:.0f} s for {scene.duration_s:g} s simulated\n")
    return ex.published


# -- 1. identification ------------------------------------------------------------------

def true_friction(material: str) -> dict[str, float]:
    """The rig material's μ_s, μ_d and the β_s, β_d of ``ident_torsion``'s contact (m)."""
    mu_s, mu_d = RIG_MATERIALS[material]
    sc = load_scene_by_name("ident_torsion")
    phi = PressureModel(sc.contact, sc.pad, sc.object.pose).phi_uncached(sc.finger.f_initial_N, 0j, 0.0)
    mean_distance = torsional_coefficient(phi, sc.pad.positions, 1.0).beta_m
    return {"mu_s": mu_s, "mu_d": mu_d, "beta_s_m": mu_s * mean_distance, "beta_d_m": mu_d * mean_distance}


def identified_material(material: str, cache: Path, rates: tuple[float, float]) -> Path:
    """Record the identification scenes on ``material`` and write its material file."""
    out = cache / f"material-{material}.toml"
    if out.exists():
        return out
    paths = []
    for name in IDENT_SCENES:
        path = cache / f"{name}@{material}.mcap"
        if not path.exists():
            scene = with_rig_material(load_scene_by_name(name), material)
            recording = {"recording": str(path), "record_topics": f"[{', '.join(RECORDED_TOPICS)}]"}
            _run("stack", name, scene, material, {"method": "exact", "tactile": "true", **recording}, rates)
        paths.append(path)
    found, _lines = identify_material(paths, name=material, progress=_say,
                                      provenance=f"slipstack identify on the rig's {material} contact "
                                                 f"({', '.join(IDENT_SCENES)}, lock-step, F/T {rates[0]:g} Hz, "
                                                 f"tactile {rates[1]:g} Hz)")
    _say(f"identified {material}\n")
    out.write_text(material_toml(found, f"The rig's {material} contact, identified by bench_detection.py."))
    return out


def identification_rows(materials: list[str], files: dict[str, Material]) -> list[str]:
    """One row per (material, coefficient): truth, identified ± 2 SE, model error, the
    ± 2-sigma interval ``2·√(SE² + model²)`` in % of the value, and whether it holds the truth."""
    rows = ["| contact | quantity | truth | identified ± 2 SE (stat) | model error | ± 2 sigma (stat + model) "
            "| error | truth inside |", "| --- | --- | ---: | ---: | ---: | ---: | ---: | :---: |"]
    for material in materials:
        truth, found = true_friction(material), files[material]
        for key, scale, unit in (("mu_s", 1, ""), ("mu_d", 1, ""), ("beta_s_m", 1e3, " mm"), ("beta_d_m", 1e3, " mm")):
            stem = key.removesuffix("_m")
            suffix = "_m" if key.endswith("_m") else ""
            value, true = getattr(found, key), truth[key]
            se, model = getattr(found, f"{stem}_se{suffix}"), getattr(found, f"{stem}_model{suffix}")
            half = interval_half_width(se, model)
            inside = "yes" if abs(value - true) <= half else "no"
            rows.append(f"| {material} | {stem} | {true * scale:.4f}{unit} | {value * scale:.4f} ± "
                        f"{2 * se * scale:.4f}{unit} | {model * scale:.4f}{unit} | ± {half * scale:.4f}{unit} "
                        f"({100 * half / value:.1f} %) | {100 * (value / true - 1):+.1f} % | {inside} |")
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


def recorded_scene(scene_name: str, material: str, cache: Path, rates: tuple[float, float]) -> dict[str, np.ndarray]:
    """γ of the launch file's deciding test on every frame, and the truth (cached)."""
    path = cache / f"{scene_name}@{material}.npz"
    if path.exists():
        return dict(np.load(path))
    base = scene_name if scene_name in DETECTION_SCENES else "stack"
    args = load_launch_file(base, builtins={"run_dir": "/tmp"}).args
    file_name = f"{scene_name}_{material}" if scene_name in NEGATIVE_SCENES else scene_name
    scene = with_rig_material(with_rates(load_scene_by_name(file_name), *rates, 1000.0), material)
    tactile = bool(args["tactile"]) and scene.tactile.enabled
    published = _run(base, file_name, scene, material, {"tactile": str(tactile).lower(), "record": "false"}, rates)
    slips, truth = published["slip"], published["rig/truth"]
    _say(f"{scene.name}: true load factors")
    data = {
        "t": np.array([m.header.stamp_ns for m in slips], dtype=np.int64),
        "contact": np.array([m.state != "no-contact" for m in slips]),
        "gamma": np.array([1.0 - m.margin if m.status == "ok" else np.nan for m in slips], dtype=float),
        "truth_t": np.array([m.header.stamp_ns for m in truth], dtype=np.int64),
        "gross": np.array([m.gross_slip for m in truth]),
        "true_gamma": true_load_factors(scene, truth),
        "method": np.array(args["method"]),
    }
    cache.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, **data)
    return data


@dataclass
class Tally:
    """Sums of one table row over scenes."""

    episodes: int = 0
    missed: int = 0
    stick_frames: int = 0
    false_frames: int = 0
    false_raised: int = 0
    tactile_stick_frames: int = 0
    tactile_false_frames: int = 0
    ft_stick_frames: int = 0
    ft_false_frames: int = 0
    negative_raised: int = 0
    negative_flagged: int = 0
    negative_frames: int = 0

    def __post_init__(self) -> None:
        self.delays: list[float] = []
        self.hold_all: list[float] = []
        self.hold_release: list[float] = []
        self.hold_between: list[float] = []


def evaluate(data: dict[str, np.ndarray], material: Material, contact: str, tally: Tally, period_ns: float,
             negative: bool) -> None:
    """Run the latch with ``material``'s thresholds over one recording; add to ``tally``."""
    thr = detector_thresholds(material)
    sigma = material.gamma_noise_stick if math.isfinite(material.gamma_noise_stick) else 0.0
    slide_sigma = material.gamma_noise_slide if math.isfinite(material.gamma_noise_slide) else 0.0
    latch = SlipLatch(DetectorConfig(delta=thr.delta, gamma_release=thr.gamma_release, gamma_resume=thr.gamma_resume))
    gamma = data["gamma"] * RECORD_MU / material.mu_s
    margin = 1.0 - gamma
    flags = np.array([latch.update(int(t), float(m), in_contact=bool(c))
                      for t, m, c in zip(data["t"], margin, data["contact"])])
    raised = flags & ~np.concatenate([[False], flags[:-1]])
    tt = data["truth_t"]
    nearest = np.clip(np.searchsorted(tt, data["t"]), 0, tt.size - 1)
    gross, true_gamma = data["gross"][nearest], data["true_gamma"][nearest]
    if negative:
        tally.negative_raised += int(raised.sum())
        tally.negative_flagged += int(flags.sum())
        tally.negative_frames += int(flags.size)
    sticking = ~gross & data["contact"]
    in_band = flags & (margin <= thr.delta)
    wrong = in_band & sticking & (true_gamma < 1.0 - thr.delta - sigma)
    tally.stick_frames += int(sticking.sum())
    tally.false_frames += int(wrong.sum())
    tally.false_raised += int((raised & wrong).sum())
    if str(data["method"]) in TACTILE_TESTS:
        tally.tactile_stick_frames += int(sticking.sum())
        tally.tactile_false_frames += int(wrong.sum())
    else:
        tally.ft_stick_frames += int(sticking.sum())
        tally.ft_false_frames += int(wrong.sum())
    episodes = find_episodes(tt, data["gross"], min_gap_ns=GAP_NS)
    t = data["t"]
    for i, ep in enumerate(episodes):
        tally.episodes += 1
        window = (t >= ep.start_ns - LEAD_NS) & (t <= ep.end_ns + GRACE_NS)
        hits = np.flatnonzero(window & flags)
        if not hits.size:
            tally.missed += 1
            continue
        tally.delays.append((t[hits[0]] - ep.start_ns) / period_ns)
        stop = episodes[i + 1].start_ns if i + 1 < len(episodes) else t[-1]
        after = np.flatnonzero((t > ep.end_ns) & (t <= stop))
        if not after.size:
            continue
        down = np.flatnonzero(~flags[after])
        end = t[after[down[0]]] if down.size else stop
        held = after[t[after] < end]
        tally.hold_all.append((end - ep.end_ns) / 1e6)
        below = held[true_gamma[held] < thr.gamma_release - slide_sigma]
        if below.size:
            tally.hold_release.append((end - t[below[0]]) / 1e6)
        else:
            tally.hold_between.append((end - ep.end_ns) / 1e6)


def _pct(values: list[float], q: float, fmt: str = "{:.1f}") -> str:
    return fmt.format(float(np.percentile(values, q))) if values else "-"


def detection_row(label: str, material: Material, tally: Tally) -> str:
    thr = detector_thresholds(material)
    stick = max(tally.stick_frames, 1)
    return (f"| {label} | {thr.delta:.3f} / {thr.gamma_release:.3f} | {tally.episodes} | {tally.missed} | "
            f"{_pct(tally.delays, 50)} / {_pct(tally.delays, 95)} | {100 * tally.false_frames / stick:.2f} % "
            f"({tally.false_raised}) | {100 * tally.tactile_false_frames / max(tally.tactile_stick_frames, 1):.2f} % / "
            f"{100 * tally.ft_false_frames / max(tally.ft_stick_frames, 1):.2f} % | "
            f"{_pct(tally.hold_all, 50, '{:.0f}')} / {_pct(tally.hold_all, 95, '{:.0f}')} | "
            f"{_pct(tally.hold_release, 50, '{:.0f}')} / {_pct(tally.hold_release, 95, '{:.0f}')} "
            f"({len(tally.hold_release)}) | {_pct(tally.hold_between, 50, '{:.0f}')} / "
            f"{_pct(tally.hold_between, 95, '{:.0f}')} ({len(tally.hold_between)}) | {tally.negative_raised} "
            f"({100 * tally.negative_flagged / max(tally.negative_frames, 1):.1f} %) |")


DETECTION_HEADER = [
    "| contact, material file | δ / γ_release | episodes | missed | delay p50 / p95 (periods) | false alarms "
    "(raised) | false alarms: tactile tests / F/T tests | hold after slip: p50 / p95 ms | hold, could release: "
    "p50 / p95 ms (n) | hold, cannot tell: p50 / p95 ms (n) | negative: raised (flagged) |",
    "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--materials", nargs="+", default=list(RIG_MATERIALS), choices=list(RIG_MATERIALS),
                    help="rig materials (default: all)")
    ap.add_argument("--scenes", nargs="+", default=DETECTION_SCENES, help="detection scenes (default: all shipped)")
    ap.add_argument("--ft-rate", type=float, default=500.0, help="F/T rate (Hz), default the stack's 500")
    ap.add_argument("--tactile-rate", type=float, default=250.0, help="tactile rate (Hz), default 250")
    ap.add_argument("--cache", type=Path, default=Path("/tmp/slipstack-bench-detection-materials"),
                    help="recordings, material files and per-scene runs (delete to re-run)")
    args = ap.parse_args()
    print_versions()
    args.cache.mkdir(parents=True, exist_ok=True)
    rates = (args.ft_rate, args.tactile_rate)
    period_ns = 1e9 / args.ft_rate
    t0 = time.monotonic()
    files = {m: load_material(identified_material(m, args.cache, rates)) for m in args.materials}
    runs = {(s, m): recorded_scene(s, m, args.cache, rates) for m in args.materials
            for s in args.scenes + NEGATIVE_SCENES}
    print(f"\nwall time {time.monotonic() - t0:.0f} s (cache {args.cache})\n")
    print("Identification (ident_force + ident_torsion, lock-step, F/T "
          f"{args.ft_rate:g} Hz, tactile {args.tactile_rate:g} Hz):\n")
    print("\n".join(identification_rows(args.materials, files)))
    print(f"\nDetection, controller off, scenes: {', '.join(args.scenes)}; negative: "
          f"{', '.join(NEGATIVE_SCENES)}; F/T period {period_ns / 1e6:g} ms\n")
    print("\n".join(DETECTION_HEADER))
    pairs = [(m, m) for m in args.materials] + [p for p in WRONG_FILES if set(p) <= set(args.materials)]
    for contact, file in pairs:
        tally = Tally()
        for scene in args.scenes + NEGATIVE_SCENES:
            evaluate(runs[(scene, contact)], files[file], contact, tally, period_ns, scene in NEGATIVE_SCENES)
        label = contact if contact == file else f"{contact}, **{file}'s file**"
        print(detection_row(label, files[file], tally))


if __name__ == "__main__":
    main()
