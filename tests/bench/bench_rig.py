#!/usr/bin/env python3
"""Lock-step speed of the simulated rig on every shipped scene, and what each shows.

Runs each scene in lock-step (as fast as possible) and prints a table: simulated
seconds, wall and CPU seconds, speed-up over real time (simulated s per wall s),
internal step, ω_c·dt of the stiffest contact mode, samples per stream, gross-slip
episodes and slip distance with the grip fixed at f_initial. ``--check`` re-runs a
scene with the grip commanded to its ``[expect] holds_at_N`` and verifies the
scene's stated outcome (slips at f_initial, holds at holds_at_N).

More in docs/modules.md, `tests/bench/bench_rig.py`.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import slipstack.launch
from slipstack.lib.rig.scene import Scene, load_scene
from slipstack.lib.samples import FtSample, TactileSample
from slipstack.lib.rig.simulator import Simulator, Truth
from _versions import print_versions

SCENES_DIR = Path(slipstack.launch.__file__).parent / "scenes"


def run(scene: Scene, hold_N: float | None = None) -> dict:
    sim = Simulator(scene)
    if hold_N is not None:
        sim.command_normal_force(hold_N)
    counts = {FtSample: 0, TactileSample: 0, Truth: 0}
    episodes, was_slipping, last = 0, False, None
    wall0, cpu0 = time.perf_counter(), time.process_time()
    for sample in sim:
        counts[type(sample)] += 1
        if isinstance(sample, Truth):
            episodes += sample.gross_slip and not was_slipping
            was_slipping = sample.gross_slip
            last = sample
    wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
    return {
        "sim_s": sim.t_ns * 1e-9, "wall_s": wall, "cpu_s": cpu,
        "step_us": sim.dt_ns / 1000, "omega_dt": sim.contact_mode_rad_s * sim.dt_ns * 1e-9,
        "ft": counts[FtSample], "tactile": counts[TactileSample], "truth": counts[Truth],
        "episodes": episodes, "slip_mm": last.slip_distance_m * 1e3,
        "slip_deg": abs(last.slip_angle_rad) * 57.29578,
    }


def with_rates(scene: Scene, rate: float | None) -> Scene:
    if rate is None:
        return scene
    return dataclasses.replace(
        scene,
        ft=dataclasses.replace(scene.ft, rate_hz=rate),
        tactile=dataclasses.replace(scene.tactile, rate_hz=rate),
        sim=dataclasses.replace(scene.sim, truth_rate_hz=rate),
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scenes", nargs="*", help="scene names or .toml paths (default: all shipped)")
    parser.add_argument("--sensor-rate", type=float, default=None,
                        help="override F/T, tactile and truth rates (Hz), e.g. 1000")
    parser.add_argument("--check", action="store_true",
                        help="also run at [expect] holds_at_N and verify the stated outcomes")
    args = parser.parse_args(argv)
    print_versions()
    paths = [Path(s) if s.endswith(".toml") else SCENES_DIR / f"{s}.toml" for s in args.scenes]
    paths = paths or sorted(SCENES_DIR.glob("*.toml"))

    head = (f"{'scene':8} {'sim s':>6} {'wall s':>7} {'cpu s':>6} {'x real':>7} {'x cpu':>6} "
            f"{'step us':>7} {'w·dt':>5} {'ft':>6} {'tact':>6} {'truth':>6} {'slips':>5} "
            f"{'mm':>6} {'deg':>6}")
    if args.check:
        head += f" {'hold N':>6} {'slips':>5} {'ok':>3}"
    print(head)
    failures = 0
    for path in paths:
        scene = with_rates(load_scene(path), args.sensor_rate)
        r = run(scene)
        line = (f"{scene.name:8} {r['sim_s']:6.1f} {r['wall_s']:7.2f} {r['cpu_s']:6.2f} "
                f"{r['sim_s'] / r['wall_s']:7.1f} {r['sim_s'] / r['cpu_s']:6.1f} "
                f"{r['step_us']:7.0f} {r['omega_dt']:5.2f} {r['ft']:6d} {r['tactile']:6d} "
                f"{r['truth']:6d} {r['episodes']:5d} {r['slip_mm']:6.2f} {r['slip_deg']:6.2f}")
        if args.check:
            ok = (r["episodes"] > 0) == scene.expect.slips_at_initial
            hold = scene.expect.holds_at_N
            if hold is not None:
                h = run(dataclasses.replace(scene, ft=dataclasses.replace(scene.ft, enabled=False),
                                            tactile=dataclasses.replace(scene.tactile, enabled=False)),
                        hold_N=hold)
                ok &= h["episodes"] == 0
                line += f" {hold:6.1f} {h['episodes']:5d}"
            else:
                line += f" {'-':>6} {'-':>5}"
            line += f" {'yes' if ok else 'NO':>3}"
            failures += not ok
        print(line, flush=True)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
