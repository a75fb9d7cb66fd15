#!/usr/bin/env python3
"""The two-finger gripper against the truth: holds, pivots and slides, in lock-step.

More in docs/modules.md, `tests/bench/bench_gripper.py`.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time

import numpy as np

from slipstack.analysis.grip_oracle import grasp_oracle_series
from slipstack.launch.lockstep import run_launch_file

HOLDS = ("grasp_rising", "grasp_pickup", "grasp_add_mass")
PIVOTS = [(angle, rate) for angle in (30, 60, 90) for rate in (20, 40, 60)]
SLIDES = [(20, 10), (20, 20)]
GOAL_AT_S = 1.5
F_NOM_N = 5.0
"""The launch file's least squeeze (the WSG 50's least force limit): no gripper squeezes less."""
LIMITS = {"ratio": 1.3, "angle_deg": 2.0, "rate": 0.2, "translation_mm": 1.0, "slide_mm": 2.0}


def run(scene: str, rates: dict[str, str], **args: str) -> dict:
    t0 = time.perf_counter()
    ex = run_launch_file("gripper", {"scene": scene, "record": "false", "monitor": "false", **rates, **args})
    truths, grasp = ex.published["rig/truth"], ex.published["rig/grasp"]
    n = min(len(truths), len(grasp))
    truths, grasp = truths[:n], grasp[:n]
    t = np.array([m.header.stamp_ns for m in truths]) * 1e-9
    out = {
        "t": t - t[0], "x": np.array([m.x for m in truths]), "y": np.array([m.y for m in truths]),
        "theta": np.array([m.theta for m in truths]), "f": np.array([m.f_n_applied for m in truths]),
        "slip_m": np.array([m.slip_distance_m for m in truths]), "slip_rad": np.array([m.slip_angle_rad for m in truths]),
        "speed": np.array([math.hypot(m.vx, m.vy) for m in truths]), "omega": np.array([m.omega for m in truths]),
        "f_t": (np.array([[m.f_x[0], m.f_y[0]] for m in grasp]), np.array([[m.f_x[1], m.f_y[1]] for m in grasp])),
        "tau": (np.array([m.tau[0] for m in grasp]), np.array([m.tau[1] for m in grasp])),
        "scene": ex.host("rig").node.scene, "wall_s": time.perf_counter() - t0,
        "ended": [m.ended for m in ex.published.get("grasp/state", []) if m.ended][-1:],
        "ended_s": next(((m.header.stamp_ns * 1e-9 - t[0]) for m in ex.published.get("grasp/state", []) if m.ended),
                        math.nan),
    }
    return out


def hold_metrics(r: dict) -> dict:
    oracle = grasp_oracle_series(r["scene"], r["x"], r["y"], r["theta"], r["f"], r["f_t"], r["tau"]).least
    ok = np.isfinite(oracle)
    # an even split: each finger carries half of the total load (finger 1's in finger 0's frame)
    total_t = r["f_t"][0] + r["f_t"][1] * np.array([-1.0, 1.0])
    total_tau = r["tau"][0] - r["tau"][1]
    half_t, half_tau = 0.5 * total_t, 0.5 * total_tau
    even = grasp_oracle_series(r["scene"], r["x"], r["y"], r["theta"], r["f"],
                               (half_t, half_t * np.array([-1.0, 1.0])), (half_tau, -half_tau)).least
    floored = np.maximum(oracle[ok], F_NOM_N)
    return {"slip_mm": 1e3 * float(r["slip_m"][-1]), "slip_deg": math.degrees(abs(float(r["slip_rad"][-1]))),
            "mean_n": float(r["f"][ok].mean()), "oracle_n": float(oracle[ok].mean()),
            "ratio": float(r["f"][ok].mean() / oracle[ok].mean()), "oracle_floored_n": float(floored.mean()),
            "ratio_floored": float(r["f"][ok].mean() / floored.mean()), "even_split_n": float(np.nanmean(even)),
            "oracle_nan": int((~ok).sum()), "wall_s": r["wall_s"]}


def motion_metrics(r: dict, target: float, rate: float, angular: bool) -> dict:
    """Final error, mean rate and translation of a pivot (deg) or a slide (mm) from the goal on."""
    t = r["t"]
    goal = np.searchsorted(t, GOAL_AT_S)
    if angular:
        moved = np.degrees(np.abs(r["theta"] - r["theta"][goal]))
    else:
        moved = 1e3 * np.hypot(r["x"] - r["x"][goal], r["y"] - r["y"][goal])
    threshold = 0.5
    start = goal + int(np.argmax(moved[goal:] > threshold))
    final = float(moved[-1])
    end = int(np.searchsorted(t, r["ended_s"])) if math.isfinite(r["ended_s"]) else len(t) - 1
    end = min(end, len(t) - 1)
    mean_rate = (moved[end] - moved[start]) / (t[end] - t[start]) if end > start else math.nan
    last_second = np.searchsorted(t, t[-1] - 1.0)
    moving_at_end = bool(moved[-1] - moved[last_second] > 2.0)  # still turning (°) or moving (mm): not held
    return {"target": target, "rate": rate, "final": final, "error": final - target, "mean_rate": float(mean_rate),
            "rate_error": float(mean_rate / rate - 1.0), "translation_mm": 1e3 * float(r["slip_m"][-1] - r["slip_m"][goal]),
            "dropped": bool(moving_at_end), "ended": r["ended"], "wall_s": r["wall_s"]}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--only", nargs="*", choices=("holds", "pivots", "slides"), default=("holds", "pivots", "slides"))
    ap.add_argument("--paper", action="store_true", help="F/T 1 kHz and tactile 500 Hz (default: 500 and 250 Hz)")
    ap.add_argument("--json", help="also write the results here")
    args = ap.parse_args()
    rates = {"ft_rate_hz": "1000", "tactile_rate_hz": "500"} if args.paper else {}
    results: dict = {"holds": {}, "pivots": [], "slides": []}
    if "holds" in args.only:
        for scene in HOLDS:
            m = hold_metrics(run(scene, rates))
            results["holds"][scene] = m
            print(f"{scene}: slip {m['slip_mm']:.3f} mm {m['slip_deg']:.3f}°, mean squeeze {m['mean_n']:.2f} N, oracle "
                  f"{m['oracle_n']:.2f} N, ratio {m['ratio']:.3f} (oracle ≥ {F_NOM_N:g} N: {m['oracle_floored_n']:.2f} N, "
                  f"ratio {m['ratio_floored']:.3f}; an even split would use {m['even_split_n']:.2f} N;"
                  f" {m['wall_s']:.0f} s)", flush=True)
    if "pivots" in args.only:
        for angle, rate in PIVOTS:
            m = motion_metrics(run("grasp_pivot", rates, goal="pivot", angle_deg=str(angle), rate_deg_s=str(rate),
                                   goal_at_s=str(GOAL_AT_S), check="false"), angle, rate, True)
            results["pivots"].append(m)
            print(f"pivot {angle}° at {rate}°/s: final {m['final']:.2f}° (error {m['error']:+.2f}°), mean rate "
                  f"{m['mean_rate']:.1f}°/s ({100 * m['rate_error']:+.1f} %), translation {m['translation_mm']:.3f} mm, "
                  f"dropped {m['dropped']}, ended {m['ended']} ({m['wall_s']:.0f} s)", flush=True)
    if "slides" in args.only:
        for dist, speed in SLIDES:
            m = motion_metrics(run("grasp_slide", rates, goal="slide", distance_mm=str(dist), speed_mm_s=str(speed),
                                   goal_at_s=str(GOAL_AT_S), check="false"), dist, speed, False)
            results["slides"].append(m)
            print(f"slide {dist} mm at {speed} mm/s: final {m['final']:.2f} mm (error {m['error']:+.2f} mm), mean speed "
                  f"{m['mean_rate']:.1f} mm/s, dropped {m['dropped']}, ended {m['ended']} ({m['wall_s']:.0f} s)", flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=1, default=str)
    failed = [f"{s}: ratio {m['ratio']:.3f} or slip" for s, m in results["holds"].items()
              if m["ratio"] > LIMITS["ratio"] or m["slip_mm"] > 0.0]
    failed += [f"pivot {m['target']}° {m['rate']}°/s" for m in results["pivots"]
               if abs(m["error"]) > LIMITS["angle_deg"] or abs(m["rate_error"]) > LIMITS["rate"]
               or m["translation_mm"] > LIMITS["translation_mm"] or m["dropped"]]
    failed += [f"slide {m['target']} mm {m['rate']} mm/s" for m in results["slides"]
               if abs(m["error"]) > LIMITS["slide_mm"] or m["dropped"]]
    print("PASS" if not failed else "FAIL: " + "; ".join(failed))
    return 0 if not failed else 1


if __name__ == "__main__":
    sys.exit(main())
