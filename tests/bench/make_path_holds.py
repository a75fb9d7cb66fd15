"""Write the rig's holds at 95 % of where their own load path lets go (launch/scenes/hold95path_*).

Per rig material and load path (a pull on the flat pad, a twist of the Hertzian tip, a force
5 mm off its centre) a probe (the ramp carried on past slip, then held) runs on the simulator;
the truth's first gross-slip onset gives the load carried there (or the most carried, if the
contact only creeps), and the hold ramps to 95 % of it in 1.5 s and keeps it 3.5 s; the hold
is run to say whether it sticks (``--check``: only that). bench_detection.py scores them.
Re-run after a change of the rig's physics: ``make_path_holds.py [--materials ...] [--paths ...]``.
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import slipstack.launch
from slipstack.lib.rig.scene import RIG_MATERIALS, Scene, Segment, load_scene
from slipstack.lib.rig.simulator import Simulator, Truth

SCENES = Path(slipstack.launch.__file__).parent / "scenes"
RAMP_S, HOLD_S, SHARE = 1.5, 3.5, 0.95
PROBE_SCALE = 1.3
"""The probe ramps to this multiple of the rigid limit, at the hold's rate."""

PATHS = {
    # path: (geometry, load direction (f_x N, f_y N, τ N·m) per unit of the rigid limit, point m, dofs)
    "force": ('model = "flat"\nfootprint = "pad"', (1.0, 0.0, 0.0), (0.0, 0.0)),
    "torsion": ('model = "hertz"\na_ref_m = 0.005\nf_ref_N = 5.0', (0.0, 0.0, 1.0), (0.0, 0.0)),
    "combined": ('model = "hertz"\na_ref_m = 0.005\nf_ref_N = 5.0', (0.0, 1.0, 0.0), (0.005, 0.0)),
}
F_N = 5.0
RIGID_TORSION_M = 2.98e-3
"""The Hertzian tip's pressure-weighted mean taxel distance at 5 N (m): β_s = μ_s × it."""


def scene_text(name: str, material: str, path: str, peak: tuple[float, float, float], ramp_s: float, hold_s: float,
               comment: str) -> str:
    geometry, _, point = PATHS[path]
    force = f"force_N = [{peak[0]:.6g}, {peak[1]:.6g}]\n" if path != "torsion" else ""
    torque = f"torque_Nm = {peak[2]:.6g}\n" if path == "torsion" else ""
    return (f"{comment}name = \"{name}\"\ndescription = \"Negative: a {path} load held at 95% of where the {material} "
            f"contact lets go on that path\"\nseed = 23\nduration_s = {ramp_s + hold_s:g}\n\n"
            "[object]\nmass_kg = 0.2\ninertia_kgm2 = 4e-5\n\n"
            f"[contact]\n{geometry}\nmaterial = \"{material}\"\n\n[dof]\nfree = [\"x\", \"y\", \"theta\"]\n\n"
            f"[finger]\nf_initial_N = {F_N:g}\n\n[disturbance]\nmode = \"wrench\"\npoint_m = [{point[0]:g}, {point[1]:g}]\n"
            f"[[disturbance.segments]]\nkind = \"ramp\"\nduration_s = {ramp_s:g}\n{force}{torque}"
            f"[[disturbance.segments]]\nkind = \"hold\"\nduration_s = {hold_s:g}\n\n[expect]\nslips_at_initial = false\n")


def truth_samples(scene: Scene, label: str) -> Iterator[Truth]:
    """The scene's truth, its sensors off, with its progress on stderr."""
    scene = replace(scene, ft=replace(scene.ft, enabled=False), tactile=replace(scene.tactile, enabled=False))
    shown = -1
    for sample in Simulator(scene):
        if not isinstance(sample, Truth):
            continue
        if int(sample.stamp_ns // 100_000_000) > shown:  # every 0.1 s simulated
            shown = int(sample.stamp_ns // 100_000_000)
            print(f"\r  {label}: {shown / 10:.1f} of {scene.duration_s:g} s simulated", end="", file=sys.stderr, flush=True)
        yield sample


def hold_verdict(name: str) -> str:
    """Whether the written hold ``name`` sticks in the rig's truth (a negative must)."""
    slip = next((s.stamp_ns * 1e-9 for s in truth_samples(load_scene(SCENES / f"{name}.toml"), name) if s.gross_slip),
                math.nan)
    print(file=sys.stderr)
    return "sticks (no gross slip)" if math.isnan(slip) else f"SLIPS from {slip:.3f} s: not a negative scene"


def onset_load(material: str, path: str) -> tuple[float, float, float, float]:
    """(f_x N, f_y N, τ N·m, t s): the load the contact carried at the probe's first gross-slip
    onset, or the largest along the path if it never slipped (t NaN)."""
    mu_s = RIG_MATERIALS[material][0]
    direction = PATHS[path][1]
    limit = mu_s * F_N * (RIGID_TORSION_M if path == "torsion" else 1.0)
    peak = tuple(PROBE_SCALE * limit * d for d in direction)
    with tempfile.TemporaryDirectory() as folder:
        probe = Path(folder) / "probe.toml"
        # whole ms: the simulator's samples() never ends on a duration off its step grid
        probe.write_text(scene_text("probe", material, path, peak, round(RAMP_S * PROBE_SCALE / SHARE, 3), HOLD_S, ""))
        scene = load_scene(probe)
    most, largest = 0.0, (0.0, 0.0, 0.0, math.nan)
    for sample in truth_samples(scene, f"probe {material} {path}"):
        if sample.gross_slip:
            return (*sample.load_force, sample.load_torque, sample.stamp_ns * 1e-9)
        along = abs(sample.load_torque) if path == "torsion" else math.hypot(*sample.load_force)
        if along > most:
            most, largest = along, (*sample.load_force, sample.load_torque, math.nan)
    return largest


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--materials", nargs="+", choices=list(RIG_MATERIALS), default=list(RIG_MATERIALS))
    ap.add_argument("--paths", nargs="+", choices=list(PATHS), default=list(PATHS))
    ap.add_argument("--check", action="store_true", help="only run the written holds and say whether each sticks")
    args = ap.parse_args()
    for material in args.materials:
        for path in args.paths:
            if args.check:
                print(f"hold95path_{path}_{material}: {hold_verdict(f'hold95path_{path}_{material}')}")
                continue
            f_x, f_y, tau, t_s = onset_load(material, path)
            print(file=sys.stderr)
            peak = (SHARE * f_x, SHARE * f_y, SHARE * tau)
            name = f"hold95path_{path}_{material}"
            when = (f"gross slip at {t_s:.3f} s carrying" if math.isfinite(t_s) else
                    "no gross slip: it creeps at its limit, carrying at most")
            comment = (f"# Negative scene, {material} contact: the {path} load ramped to 95 % of the load at which the\n"
                       f"# same ramp, carried on, lets go (the rig's truth: {when} f = ({f_x:.4g}, {f_y:.4g}) N,\n"
                       f"# τ = {tau:.4g} N·m about the pad origin), then held. Written by "
                       "tests/bench/make_path_holds.py; no controller.\n")
            (SCENES / f"{name}.toml").write_text(scene_text(name, material, path, peak, RAMP_S, HOLD_S, comment))
            print(f"{name}: onset at {t_s:.3f} s, f ({f_x:.4f}, {f_y:.4f}) N, tau {tau:.6f} N·m; hold at 95 %"
                  f" ({math.hypot(peak[0], peak[1]):.4f} N, {peak[2]:.6f} N·m); the hold {hold_verdict(name)}")


if __name__ == "__main__":
    main()
