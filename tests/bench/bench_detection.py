"""Detection quality of every slip test over the shipped scenes (issue 6, Must show 2).

Each scene runs once in lock-step (``nodes/lockstep.py``: the real driver, fusion and
detector nodes on device-codec bytes, controller off, so every slip the scene
provokes happens) at the stack's default rates (F/T 500 Hz, tactile 250 Hz; truth
1 kHz). The slip detector publishes every test's margin on every frame; each test's
margins then go through the same latch (``lib/detection.py``) for each onset band δ,
and are matched to the rig's true gross-slip episodes (``lib/episodes.py``):
median and p95 delay from true onset to the first slip verdict (negative: warned
before gross slip), false-slip rate on truly sticking frames (partial slip with at
least a quarter of the friction capacity sliding counts as incipient, not sticking), and
missed episodes. False-slip frames are split by cause: *onset band* (the frame's own
margin is ≤ δ: the load is near the limit although the contact sticks — the price of δ)
and *latch hold* (the latch kept an earlier verdict, γ ≥ γ_release, after the object
re-stuck). Onset-band frames are checked against the *true* load factor (the true
load on the true pressure, μ_s): where it is ≥ 1 − δ too, the measurement was right and
the verdict is the band's intended early warning on a contact that has not yet slipped.
The tactile tests run only on scenes with a tactile pad (the ``scenes``
column); on the F/T-only scenes (fig10–12) they are not applicable.

    python tests/bench/bench_detection.py                 # all scenes, δ sweep
    python tests/bench/bench_detection.py --scenes fig15 --deltas 0.05 0.1
    python tests/bench/bench_detection.py --gamma-release 0.7 --release-ms 30   # other latch
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from slipstack.lib.detection import DetectorConfig, SlipLatch
from slipstack.lib.episodes import INCIPIENT_SHARE, DetectionQuality, detection_quality
from slipstack.lib.limit_set import load_factor
from slipstack.lib.rig.contact import PressureModel
from slipstack.lib.rig.scene import Scene
from slipstack.launch.launch_file import load_launch_file
from slipstack.nodes.lockstep import LockstepStack, StackConfig, load_scene_by_name
from slipstack.nodes.rig import with_rates

SCENES = ["fig4a", "fig4b", "fig10", "fig11", "fig12", "fig13", "fig14", "fig15", "default"]
FT_TESTS = ["coulomb", "decoupled", "linear_ls", "elliptic_ls"]
TACTILE_TESTS = ["tactile_cor", "tactile_cor_robust", "exact"]


def _scene_args(scene: str) -> dict:
    """The launch arguments the scene's own launch file sets (beta_m, tactile)."""
    lf = load_launch_file(scene, builtins={"run_dir": "/tmp"})
    return lf.args


def record_scene(scene: str, cache: Path, ft_hz: float, tactile_hz: float) -> dict[str, np.ndarray]:
    """Run ``scene`` with the controller off; return (and cache) the margins and truth."""
    path = cache / f"{scene}-{ft_hz:g}-{tactile_hz:g}.npz"
    if path.exists():
        cached = dict(np.load(path))
        if "true_gamma" in cached:  # older caches lack it: record again
            return cached
    args = _scene_args(scene)
    sc = with_rates(load_scene_by_name(args["scene"]), ft_hz, tactile_hz, 1000.0)
    tests = (FT_TESTS + TACTILE_TESTS) if sc.tactile.enabled and args["tactile"] else FT_TESTS
    slip = {"method": tests[-1], "also": tests, "beta_m": float(args["beta_m"]), "mu": float(args["mu"])}
    stack = LockstepStack(sc, StackConfig(controller=False, tactile=bool(args["tactile"]), slip=slip))
    t0 = time.monotonic()
    ex = stack.run(progress=lambda f: print(f"\r  {scene}: {100 * f:5.1f}% ", end="", file=sys.stderr, flush=True))
    print(f"\r  {scene}: done in {time.monotonic() - t0:.0f} s ({sc.duration_s:g} s simulated)", file=sys.stderr)
    stack.close()
    slips = ex.published["slip"]
    truth = ex.published["rig/truth"]
    data = {
        "t": np.array([m.header.stamp_ns for m in slips], dtype=np.int64),
        "contact": np.array([m.state != "no-contact" for m in slips]),
        "truth_t": np.array([m.header.stamp_ns for m in truth], dtype=np.int64),
        "gross": np.array([m.gross_slip for m in truth]),
        "sliding": np.array([m.sliding_fraction for m in truth]),
        "true_gamma": true_load_factors(sc, truth),
        "tests": np.array(tests),
    }
    for name in tests:
        data[f"margin_{name}"] = np.array([m.verdicts.get(name, [False, np.nan])[1] for m in slips], dtype=float)
    cache.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, **data)
    return data


def true_load_factors(scene: Scene, truth: list) -> np.ndarray:
    """γ of the *true* load on the *true* pressure at each truth sample (μ_s, no sensor).

    The pressure is the scene's model at the applied normal force and the object's pose
    (without the simulator's shape cache); the load is the disturbance's, at the pad.
    NaN where no γ.
    """
    P, mu_s = scene.pad.positions, scene.contact.mu_s
    pressure = PressureModel(scene.contact, scene.pad, scene.object.pose)
    out = np.full(len(truth), np.nan)
    for i, tr in enumerate(truth):
        phi = pressure.phi_uncached(tr.f_n_applied, complex(tr.x, tr.y), tr.theta)
        r = load_factor(phi, P, tr.load_f_t, tr.load_tau, mu_s)
        if r.status.usable:
            out[i] = r.gamma
    return out


def evaluate(data: dict[str, np.ndarray], test: str, delta: float,
             gamma_release: float = DetectorConfig.gamma_release,
             release_ns: int = DetectorConfig.release_ns) -> tuple[DetectionQuality, int, int]:
    """Latch one test's margins at ``delta``; match them to the true episodes.

    Returns the quality, how many of its false-slip frames are onset-band frames, and
    how many of those carried a true load factor (:func:`true_load_factors`) ≥ 1 − δ.
    """
    latch = SlipLatch(DetectorConfig(delta=delta, gamma_release=gamma_release, release_ns=release_ns))
    margins = data[f"margin_{test}"]
    flags = np.array([latch.update(int(t), float(m), in_contact=bool(c))
                      for t, m, c in zip(data["t"], margins, data["contact"])])
    incipient = data["sliding"] >= INCIPIENT_SHARE
    q = detection_quality(data["truth_t"], data["gross"], data["t"], flags, incipient=incipient)
    in_band = flags & (margins <= delta)  # NaN margins compare False: held, not onset
    onset = detection_quality(data["truth_t"], data["gross"], data["t"], in_band, incipient=incipient)
    nearest = np.clip(np.searchsorted(data["truth_t"], data["t"]), 0, data["truth_t"].size - 1)
    at_limit = data["true_gamma"][nearest] >= 1.0 - delta  # NaN compares False
    truly = detection_quality(data["truth_t"], data["gross"], data["t"], in_band & at_limit, incipient=incipient)
    return q, onset.false_slip_frames, truly.false_slip_frames


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", nargs="+", default=SCENES, help="scene names (default: all shipped)")
    ap.add_argument("--deltas", nargs="+", type=float, default=[0.05, 0.1, 0.15, 0.18, 0.25], help="onset bands δ")
    ap.add_argument("--ft-rate", type=float, default=500.0, help="F/T rate (Hz), default the stack's 500")
    ap.add_argument("--tactile-rate", type=float, default=250.0, help="tactile rate (Hz), default 250")
    ap.add_argument("--gamma-release", type=float, default=DetectorConfig.gamma_release,
                    help="latch release level γ_release (default: the detector's, %(default)g)")
    ap.add_argument("--release-ms", type=float, default=DetectorConfig.release_ns / 1e6,
                    help="latch release dwell in ms (default: the detector's, %(default)g)")
    ap.add_argument("--cache", type=Path, default=Path("/tmp/slipstack-bench-detection"),
                    help="where the per-scene runs are cached (delete to re-run)")
    args = ap.parse_args()
    period_ms = 1000.0 / args.ft_rate
    runs = {s: record_scene(s, args.cache, args.ft_rate, args.tactile_rate) for s in args.scenes}
    tests = [t for t in FT_TESTS + TACTILE_TESTS if any(t in r["tests"] for r in runs.values())]
    print(f"\nDetection quality, controller off, F/T {args.ft_rate:g} Hz (period {period_ms:g} ms), "
          f"tactile {args.tactile_rate:g} Hz; latch release γ < {args.gamma_release:g} for {args.release_ms:g} ms; "
          f"scenes: {', '.join(args.scenes)}\n")
    print("| test | δ | scenes | episodes | missed | delay p50 ms | delay p95 ms | p95 ≤ 2 periods "
          "| false-slip rate | onset band | … true γ ≥ 1−δ | latch hold |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | :---: | ---: | ---: | ---: | ---: |")
    for test in tests:
        for delta in args.deltas:
            scenes = episodes = missed = false = onset = truly = stick = 0
            delays: list[int] = []
            for data in runs.values():
                if test not in data["tests"]:
                    continue
                q, in_band, at_limit = evaluate(data, test, delta, args.gamma_release, round(args.release_ms * 1e6))
                scenes += 1
                episodes += len(q.episodes)
                missed += q.missed
                delays += list(q.delays_ns)
                false += q.false_slip_frames
                onset += in_band
                truly += at_limit
                stick += q.stick_frames
            d = np.array(delays, dtype=float) / 1e6
            p50 = f"{np.percentile(d, 50):.1f}" if d.size else "-"
            p95v = float(np.percentile(d, 95)) if d.size else float("nan")
            ok = "yes" if d.size and p95v <= 2 * period_ms and missed == 0 else "no"
            pct = [f"{100 * n / stick:.3f}%" if stick else "-" for n in (false, onset, truly, false - onset)]
            print(f"| {test} | {delta:g} | {scenes} | {episodes} | {missed} | {p50} | "
                  f"{'-' if not d.size else f'{p95v:.1f}'} | {ok} | {' | '.join(pct)} |")

if __name__ == "__main__":
    main()
