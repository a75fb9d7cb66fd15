#!/usr/bin/env python3
"""Grip economy: how much normal force each grip law spends to hold a disturbance.

For each scene and grip law the launch file ``stack`` runs in lock-step with the
simulated rig (``slipstack launch stack --lockstep``, ``launch/lockstep.py``: controller
on, its sensor rates, material and law parameters; f_max = the scene's finger limit).
Laws (docs/math.md §5):

More in docs/modules.md, `tests/bench/bench_grip_economy.py`.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from slipstack.lib.limit_set import torsional_coefficient
from slipstack.lib.rig.contact import PressureModel
from slipstack.lib.rig.scene import Scene
from slipstack.launch.launch_file import load_launch_file
from slipstack.launch.lockstep import run_launch_file
from slipstack.analysis.grip_oracle import oracle_series
from slipstack.nodes.rig import load_scene_by_name
from _versions import print_versions

DEFAULT_SCENES = ["fig12", "fig14", "fig15", "default"]
DEFAULT_LAWS = ["ft13", "tactile14", "tactile14:delta=0.25", "exact"]
FT_ONLY_LAWS = {"linear", "ft13", "ft13_sigma"}
STACK_ARGS = load_launch_file("stack", builtins={"run_dir": "/nonexistent"}).args
HOLD_MM, HOLD_DEG = 0.5, 0.5
WALL_PER_SIM_S = 1.5  # measured lock-step cost on the 2-core dev machine, plus the oracle


def prepare(name: str) -> tuple[Scene, float]:
    """The scene and its contact's true ``β_s`` (m)."""
    scene = load_scene_by_name(name)
    pm = PressureModel(scene.contact, scene.pad, scene.object.pose)
    x, y, th = scene.object.pose
    phi = pm.phi(scene.finger.f_initial_N, complex(x, y), th)
    beta = torsional_coefficient(phi, scene.pad.positions, scene.contact.mu_s).beta_m
    return scene, beta


def parse_law(spec: str) -> tuple[str, dict[str, str]]:
    """``"tactile14:delta=0.25"`` → ``("tactile14", {"delta": "0.25"})`` (launch arguments)."""
    law, _, rest = spec.partition(":")
    extra = {}
    for item in filter(None, rest.split(",")):
        key, _, value = item.partition("=")
        extra[key.strip()] = value.strip()
    return law, extra


def launch_args(spec: str, scene: Scene, beta_m: float, f_nom_n: float) -> dict[str, str]:
    """The arguments of ``stack.toml`` for law ``spec`` on ``scene``."""
    law, extra = parse_law(spec)
    args = {"scene": scene.name, "law": law, "f_nom_n": str(f_nom_n), "f_max_n": str(scene.finger.f_max_N),
            "record": "false", "monitor": "false"}
    if law in FT_ONLY_LAWS:
        args |= {"tactile": "false", "method": "linear_ls", "beta_m": str(beta_m)}
    else:
        args |= {"tactile": "true", "method": "exact", "cor_solver": "exact"}
    return args | extra


def runnable(spec: str, scene: Scene) -> bool:
    """A law that needs the tactile pad runs only on a scene that simulates one."""
    return parse_law(spec)[0] in FT_ONLY_LAWS or scene.tactile.enabled


def run_one(scene: Scene, law: str, beta_m: float, f_nom_n: float, label: str) -> dict[str, np.ndarray]:
    """Run the stack; per-truth-sample series (SI) plus the oracle."""
    marks = iter(np.arange(0.1, 1.01, 0.1))
    mark = next(marks)
    t0 = time.perf_counter()

    def progress(frac: float) -> None:
        nonlocal mark
        while mark is not None and frac >= mark - 1e-9:
            print(f"  {label}: {mark:4.0%} ({time.perf_counter() - t0:5.1f} s)", file=sys.stderr, flush=True)
            mark = next(marks, None)

    ex = run_launch_file("stack", launch_args(law, scene, beta_m, f_nom_n), progress=progress)
    truths = ex.published["rig/truth"]
    commands = ex.published["grip/command"]
    oracle = oracle_series(scene, np.array([tr.x for tr in truths]), np.array([tr.y for tr in truths]),
                           np.array([tr.theta for tr in truths]), np.array([tr.f_n_applied for tr in truths]),
                           np.array([tr.load_f_t for tr in truths]), np.array([tr.load_tau for tr in truths]))
    print(f"  {label}: done in {time.perf_counter() - t0:.1f} s", file=sys.stderr, flush=True)
    return {
        "t": np.array([tr.header.stamp_ns for tr in truths]) * 1e-9,
        "f_cmd": np.array([tr.f_n_command for tr in truths]),
        "f_app": np.array([tr.f_n_applied for tr in truths]),
        "slip_mm": np.array([tr.slip_distance_m for tr in truths]) * 1e3,
        "slip_deg": np.degrees(np.abs([tr.slip_angle_rad for tr in truths])),
        "f_t": np.array([np.hypot(*tr.load_f_t) for tr in truths]),
        "tau": np.array([tr.load_tau for tr in truths]),
        "oracle": oracle.least,
        "oracle_frozen": oracle.frozen,
        "peak_cmd": np.array([max((c.f_n_desired for c in commands), default=math.nan)]),
    }


def cached_run(cache: Path | None, scene: Scene, law: str, beta_m: float, f_nom_n: float, label: str) -> dict:
    if cache is None:
        return run_one(scene, law, beta_m, f_nom_n, label)
    key = json.dumps({"scene": scene.name, "law": law, "beta": beta_m, "f_nom_n": f_nom_n}, sort_keys=True)
    path = cache / f"{scene.name}_{law.replace(':', '_').replace(',', '_').replace('=', '')}.npz"
    if path.exists():
        data = dict(np.load(path))
        if str(data.pop("key")) == key:
            print(f"  {label}: cached ({path})", file=sys.stderr, flush=True)
            return data
    data = run_one(scene, law, beta_m, f_nom_n, label)
    cache.mkdir(parents=True, exist_ok=True)
    np.savez(path, key=key, **data)
    return data


def summarise(r: dict, f_nom: float) -> dict[str, float]:
    oracle = r["oracle"][np.isfinite(r["oracle"])]
    slip_mm, slip_deg = float(r["slip_mm"].max()), float(r["slip_deg"].max())
    return {
        "mean_cmd": float(r["f_cmd"].mean()), "peak_cmd": float(r["peak_cmd"][0]),
        "mean_app": float(r["f_app"].mean()), "slip_mm": slip_mm, "slip_deg": slip_deg,
        "held": slip_mm < HOLD_MM and slip_deg < HOLD_DEG,
        "o_mean": float(oracle.mean()), "o_peak": float(oracle.max()),
        "o_floor": float(np.maximum(oracle, f_nom).mean()),
        "o_frozen": float(np.nanmean(r["oracle_frozen"])),
        "o_bad": int(r["oracle"].size - oracle.size),
    }


def table(rows: list[tuple[str, float, str, dict]]) -> str:
    head = ("| scene | β_s mm | law | mean f_n cmd N | peak f_n cmd N | mean f_n applied N | held "
            "| slip mm / ° | oracle mean N | oracle peak N | oracle ≥f_nom mean N | cmd / oracle | cmd / oracle≥f_nom |")
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for scene, beta, law, m in rows:
        lines.append(
            f"| {scene} | {beta * 1e3:.2f} | {law} | {m['mean_cmd']:.2f} | {m['peak_cmd']:.2f} | {m['mean_app']:.2f} "
            f"| {'yes' if m['held'] else 'NO'} | {m['slip_mm']:.2f} / {m['slip_deg']:.2f} | {m['o_mean']:.2f} "
            f"| {m['o_peak']:.2f} | {m['o_floor']:.2f} | {m['mean_cmd'] / m['o_mean']:.2f} "
            f"| {m['mean_cmd'] / m['o_floor']:.2f} |")
    return "\n".join(lines)


def verdict(rows: list[tuple[str, float, str, dict]]) -> str:
    """Sentences comparing the laws per scene and the paper's (14) < (13) claim."""
    by_scene: dict[str, dict[str, dict]] = {}
    for scene, _, law, m in rows:
        by_scene.setdefault(scene, {})[law] = m
    out: list[str] = []
    claim: dict[str, list[bool]] = {}
    for scene, laws in by_scene.items():
        parts = [f"{law} {m['mean_cmd']:.2f} N ({m['mean_cmd'] / m['o_mean']:.2f}× oracle"
                 f"{'' if m['held'] else ', SLIPPED'})" for law, m in laws.items()]
        out.append(f"- {scene}: mean commanded f_n: " + "; ".join(parts)
                   + f"; oracle mean {next(iter(laws.values()))['o_mean']:.2f} N.")
        for name, b in laws.items():
            if "ft13" not in laws or parse_law(name)[0] != "tactile14":
                continue
            a = laws["ft13"]
            less = 1.0 - b["mean_cmd"] / a["mean_cmd"]
            ok = b["mean_cmd"] < a["mean_cmd"] and b["held"]
            claim.setdefault(name, []).append(ok)
            out.append(f"  {name} vs ft13: {b['mean_cmd']:.2f} vs {a['mean_cmd']:.2f} N mean "
                       f"({abs(less):.0%} {'less' if less > 0 else 'more'}), peak {b['peak_cmd']:.2f} vs {a['peak_cmd']:.2f} N; "
                       f"{name} held: {'yes' if b['held'] else 'NO'}, ft13 held: {'yes' if a['held'] else 'NO'} "
                       f"-> claim {'holds' if ok else 'does NOT hold'} here.")
    for name, oks in claim.items():
        out.append(f"\nPaper's claim 'both sensors (14) need less force than F/T only (13)', (14) = {name}: "
                   f"holds (holds the object with less mean force) in {sum(oks)}/{len(oks)} scenes.")
    return "\n".join(out)


def plot(path: Path, scene: str, results: dict[str, dict], f_nom: float) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, axl) = plt.subplots(2, 1, figsize=(12, 7), sharex=True, gridspec_kw={"height_ratios": [3, 1.2]})
    colours = {"ft13": "tab:red", "tactile14": "tab:blue", "exact": "tab:green",
               "linear": "tab:purple", "ft13_sigma": "tab:orange"}
    for k, (law, r) in enumerate(results.items()):
        ax.plot(r["t"], r["f_cmd"], color=colours.get(law, f"C{k + 5}"), lw=1.6, label=f"{law}: commanded f_n")
    for k, r in enumerate(results.values()):  # the runs' oracles differ only where a run slips
        ax.plot(r["t"], r["oracle"], color="k", lw=0.8, ls=":", label="oracle (each run)" if k == 0 else None)
    ax.axhline(f_nom, color="0.5", lw=0.8, ls="--", label=f"f_nom = {f_nom:g} N")
    ax.set_ylabel("normal force f_n (N)")
    ax.set_title(f"Grip economy, scene {scene}: commanded f_n per law vs the oracle\n"
                 "(oracle: least f_n that holds the true load with the true pressure, μ = μ_s)", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    r0 = next(iter(results.values()))
    axl.plot(r0["t"], r0["f_t"], color="k", lw=1.0, label="|f_t| (N)")
    axl.set_ylabel("|f_t| (N)")
    axr = axl.twinx()
    axr.plot(r0["t"], np.asarray(r0["tau"]) * 1e3, color="tab:brown", lw=1.0, label="τ (mN·m)")
    axr.set_ylabel("τ (mN·m)", color="tab:brown")
    axl.set_xlabel("time (s)")
    axl.set_title(f"true load on the {next(iter(results))} run", fontsize=9)
    axl.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter,
                                     epilog="\n\n".join(__doc__.split("\n\n")[1:]))
    parser.add_argument("--scenes", nargs="+", default=DEFAULT_SCENES,
                        help=f"scene names or .toml paths (default: {' '.join(DEFAULT_SCENES)}; fig11 is torque only)")
    parser.add_argument("--laws", nargs="+", default=DEFAULT_LAWS,
                        help=f"grip laws (default: {' '.join(DEFAULT_LAWS)}); 'law:param=value,...' sets "
                             "grip_controller parameters, e.g. tactile14:delta=0.25")
    parser.add_argument("--f-nom", type=float, default=STACK_ARGS["f_nom_n"],
                        help=f"lowest commanded f_n, N (default stack.toml's {STACK_ARGS['f_nom_n']:g})")
    parser.add_argument("--png", type=Path, help="write a figure of f_n(t) per law vs the oracle to this path")
    parser.add_argument("--png-scene", help="scene for --png (default: fig15 if run, else the first)")
    parser.add_argument("--cache", type=Path, help="directory to cache runs in (re-used when parameters match)")
    args = parser.parse_args(argv)
    print_versions()

    prepared = {name: prepare(name) for name in args.scenes}
    runs = [(sc, beta, law) for sc, beta in prepared.values() for law in args.laws if runnable(law, sc)]
    skipped = [f"{sc.name}/{law}" for sc, _ in prepared.values() for law in args.laws if not runnable(law, sc)]
    sim_s = sum(sc.duration_s for sc, _, _ in runs)
    print(f"{len(runs)} lock-step runs, {sim_s:.0f} simulated s: expect about "
          f"{sim_s * WALL_PER_SIM_S / 60:.0f} min (less with --cache hits)", file=sys.stderr, flush=True)

    rows, series = [], {}
    for scene, beta, law in runs:
        r = cached_run(args.cache, scene, law, beta, args.f_nom, f"{scene.name}/{law}")
        series.setdefault(scene.name, {})[law] = r
        rows.append((scene.name, beta, law, summarise(r, args.f_nom)))

    print(f"## Grip economy (launch file stack.toml: material {STACK_ARGS['material']}, f_nom = {args.f_nom:g} N; "
          f"F/T {STACK_ARGS['ft_rate_hz']:g} Hz, tactile {STACK_ARGS['tactile_rate_hz']:g} Hz; "
          f"held iff slip < {HOLD_MM} mm and < {HOLD_DEG}°)\n")
    if skipped:
        print(f"skipped (the scene simulates no tactile pad): {', '.join(skipped)}\n")
    print(table(rows))
    bad = sum(m["o_bad"] for *_, m in rows)
    frozen = [f"{sc}/{law} {m['o_frozen']:.2f}" for sc, _, law, m in rows if abs(m["o_frozen"] - m["o_mean"]) > 0.005 * m["o_mean"]]
    print(f"\noracle samples without a usable answer (no contact / solver): {bad}")
    if frozen:
        print("force-dependent pressure: frozen-shape γ·f_applied oracle mean (N), instead of the fixed point: "
              + ", ".join(frozen))
    print("\n" + verdict(rows))
    if args.png:
        target = args.png_scene or ("fig15" if "fig15" in series else next(iter(series)))
        plot(args.png, target, series[target], args.f_nom)
        print(f"\nfigure: {args.png} (scene {target})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
