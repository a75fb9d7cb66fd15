"""Benchmark of the slip mathematics: per-frame time of every test and solver, and accuracy.

Prints three markdown tables:

More in docs/modules.md, `tests/bench/bench_math.py`.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
from scipy.optimize import root

from slipstack.lib.cor import cor_equations, paper_cor
from slipstack.lib.limit_set import load_factor, torsional_coefficient
from slipstack.lib.pad import PadGeometry
from slipstack.lib.slip_tests import SLIP_TESTS, SlipParams
from slipstack.lib.weber import solve_weber
from _versions import print_versions

MU = 0.5


class Contact:
    """Minimal contact record for the slip tests."""

    def __init__(self, phi, f_t, tau, positions):
        self.phi, self.f_t, self.tau, self.positions = phi, np.asarray(f_t, float), float(tau), positions
        self.f_n = float(phi.sum())


def pressure_field(kind: str, pad: PadGeometry) -> np.ndarray:
    """Normal forces (N, f_n = 5 N) of a named pressure field on ``pad``."""
    x, y = pad.positions.T
    half = pad.cols * pad.pitch_m / 2
    if kind == "uniform":
        phi = (np.hypot(x, y) < 0.6 * half).astype(float)
    elif kind == "hertz":
        phi = np.sqrt(np.clip(1 - (x**2 + y**2) / (0.6 * half) ** 2, 0, None))
    elif kind == "off-centre":
        phi = np.sqrt(np.clip(1 - ((x - 0.35 * half) ** 2 + (y + 0.2 * half) ** 2) / (0.45 * half) ** 2, 0, None))
    elif kind == "two-patch":
        phi = np.sqrt(np.clip(1 - ((x - 0.5 * half) ** 2 + y**2) / (0.3 * half) ** 2, 0, None))
        phi += 0.6 * np.sqrt(np.clip(1 - ((x + 0.5 * half) ** 2 + y**2) / (0.3 * half) ** 2, 0, None))
    else:
        raise ValueError(kind)
    return phi * (5.0 / phi.sum())


def load_sequence(phi, pad, n, rng):
    """``n`` loads drifting ~1 %/frame around γ ≈ 0.3–0.9 with varying force/torque mix."""
    beta = torsional_coefficient(phi, pad.positions, MU).beta_m
    f_n = phi.sum()
    base = np.array([0.4 * MU * f_n, 0.2 * MU * f_n, 0.4 * beta * f_n])
    out, cur = [], base.copy()
    for _ in range(n):
        cur = cur * (1 + 0.01 * rng.normal(size=3))
        out.append(cur.copy())
    return out


def hybr_cor(phi, P, f_t, mu, c0, L):
    """scipy.optimize.root(hybr) on (12), sense s = +1, to ~1e-9 m.

    Solved in normalised units (c in contact radii about ``c0``, F in μ f_n) so that
    hybr's scaling and relative ``xtol`` are meaningful; the result's ``x`` is in m.
    """
    sub = phi > 0
    ph, Ps = phi[sub], P[sub]
    cap = mu * ph.sum()
    c0 = np.asarray(c0, dtype=float)

    def fun(u):
        return cor_equations(c0 + L * u, ph, Ps, f_t, mu)[0] / cap

    res = root(fun, np.zeros(2), method="hybr", options={"xtol": 1e-9})
    res.x = c0 + L * res.x
    return res


def timed(fn, frames):
    ts, out = [], []
    for fr in frames:
        t0 = time.perf_counter()
        out.append(fn(fr))
        ts.append(time.perf_counter() - t0)
    return np.array(ts) * 1e6, out


def timing_table(sizes, n_frames, rng):
    rows, agree = [], []
    for size in sizes:
        pad = PadGeometry(size, size, 20e-3 / size)
        P = pad.positions
        phi = pressure_field("hertz", pad)
        params = SlipParams(mu=MU, beta_m=torsional_coefficient(phi, P, MU).beta_m)  # F/T tests get β
        cop = phi @ P / phi.sum()
        L = math.sqrt(float(phi @ np.sum((P - cop) ** 2, axis=1)) / phi.sum())
        loads = load_sequence(phi, pad, n_frames, rng)
        frames = [Contact(phi, w[:2], w[2], P) for w in loads]
        for name, test in SLIP_TESTS.items():
            ts, _ = timed(lambda c: test(c, params), frames)
            rows.append((size, name, "cold", ts))
            if name.startswith("tactile") or name == "exact":
                prev = [None]

                def warm(c, test=test, prev=prev):
                    v = test(c, params, prev[0])
                    prev[0] = v.p_c
                    return v

                ts, _ = timed(warm, frames)
                rows.append((size, name, "warm", ts))
        # the solvers on their own
        for label, fn in (
            ("load_factor (Dinkelbach)", lambda c, c0=None: load_factor(c.phi, P, c.f_t, c.tau, MU, c0=c0)),
            ("weber s=+1 (robust (12))", lambda c, c0=None: solve_weber(
                P, MU * c.phi, (-c.f_t[1], c.f_t[0]), c0)),
            ("paper fixed-gain (12)", lambda c, c0=None: paper_cor(c.phi, P, c.f_t, c.tau, MU, c0=c0)),
            ("scipy hybr (12)", lambda c, c0=None: hybr_cor(c.phi, P, c.f_t, MU, cop if c0 is None else c0, L)),
        ):
            ts, cold_out = timed(fn, frames)
            rows.append((size, label, "cold", ts))
            prev = [None]

            def warm(c, fn=fn, prev=prev):
                res = fn(c, prev[0])
                x = res.x if hasattr(res, "x") else (res.p_c if hasattr(res, "p_c") else res.c)
                prev[0] = None if x is None else np.asarray(x)
                return res

            ts, _ = timed(warm, frames)
            rows.append((size, label, "warm", ts))
        # agreement robust (12) vs hybr (12)
        ok = 0
        for c in frames:
            a = solve_weber(P, MU * c.phi, (-c.f_t[1], c.f_t[0]))
            h = hybr_cor(c.phi, P, c.f_t, MU, cop, L)
            ok += h.success and a.c is not None and np.hypot(*(np.array(a.c) - h.x)) <= 1e-9
        agree.append((size, ok / len(frames)))
    return rows, agree


def print_timing(rows, agree):
    print("## Time per frame (µs), Hertzian contact, loads drifting 1 %/frame\n")
    print("| pad | method | start | p50 | p99 |")
    print("| --- | --- | --- | ---: | ---: |")
    for size, name, start, ts in rows:
        print(f"| {size}×{size} | {name} | {start} | {np.percentile(ts, 50):.0f} | {np.percentile(ts, 99):.0f} |")
    print("\n## Robust (12) vs scipy hybr (12)\n")
    print("| pad | hybr converged and within 1e-9 m of robust | speed-up p50 cold | speed-up p50 warm |")
    print("| --- | ---: | ---: | ---: |")
    med = {(s, n, st): np.percentile(ts, 50) for s, n, st, ts in rows}
    for size, frac in agree:
        up_c = med[(size, "scipy hybr (12)", "cold")] / med[(size, "weber s=+1 (robust (12))", "cold")]
        up_w = med[(size, "scipy hybr (12)", "warm")] / med[(size, "weber s=+1 (robust (12))", "warm")]
        print(f"| {size}×{size} | {frac:.1%} | {up_c:.1f}× | {up_w:.1f}× |")


def accuracy_table(grid_n):
    pad = PadGeometry()
    P = pad.positions
    print(f"\n## Approximate tests vs the exact test, 16×16, {grid_n}×{grid_n} loads in the (f_t, τ) plane\n")
    print("β = β_s from the tactile data (intercepts exact). Loads: f_t along x, |f_t| ≤ 1.5 μ f_n, "
          "|τ| ≤ 1.5 β_s f_n (τ about the pad origin).\n")
    print("| field | test | false stick | false slip | worst margin error | worst over-prediction of capacity |")
    print("| --- | --- | ---: | ---: | ---: | ---: |")
    for field in ("uniform", "hertz", "off-centre", "two-patch"):
        phi = pressure_field(field, pad)
        f_n = phi.sum()
        beta = torsional_coefficient(phi, P, MU).beta_m
        params = SlipParams(mu=MU, beta_m=beta)
        fts = np.linspace(0, 1.5 * MU * f_n, grid_n)
        taus = np.linspace(-1.5 * beta * f_n, 1.5 * beta * f_n, grid_n)
        exact = {}
        for ft in fts:
            for tau in taus:
                if ft == 0 and tau == 0:
                    continue
                exact[(ft, tau)] = load_factor(phi, P, (ft, 0.0), tau, MU).gamma
        for name in ("coulomb", "decoupled", "linear_ls", "elliptic_ls", "tactile_cor", "tactile_cor_robust"):
            fs = fslip = 0
            worst = over = 0.0
            for (ft, tau), g in exact.items():
                v = SLIP_TESTS[name](Contact(phi, (ft, 0.0), tau, P), params)
                fs += v.stick and g > 1
                fslip += (not v.stick) and g <= 1
                worst = max(worst, abs(v.margin - (1 - g)))
                if v.gamma > 0:
                    over = max(over, g / v.gamma - 1)  # capacity over-prediction factor
            n = len(exact)
            print(f"| {field} | {name} | {fs / n:.1%} | {fslip / n:.1%} | {worst:.3f} | {over:.1%} |")


def crosscheck(n_cases: int, rng) -> None:
    """γ vs the brute-force twist search of tests/unit/test_limit_set.py on 16×16 fields."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "unit" / "test_limit_set.py"
    spec = importlib.util.spec_from_file_location("test_limit_set", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    pad = PadGeometry()
    errs = []
    for k in range(n_cases):
        phi, f_t, tau = mod._random_case(rng, pad)
        res = load_factor(phi, pad.positions, f_t, tau, MU)
        if k % 4 == 1:  # on the boundary, and 1e-3 inside / outside it
            s = [1.0, 1 - 1e-3, 1 + 1e-3][k % 3] / res.gamma
            f_t, tau = f_t * s, tau * s
            res = load_factor(phi, pad.positions, f_t, tau, MU)
        ref = mod.brute_force_gamma(phi, pad.positions, f_t, tau, MU, n_dir=4000)
        errs.append(abs(res.gamma - ref) / ref)
    errs = np.array(errs)
    print(f"\n## Cross-check against brute force, {n_cases} random 16×16 cases\n")
    print("| cases | max rel. error | p99 rel. error | cases > 1e-6 |\n| ---: | ---: | ---: | ---: |")
    print(f"| {n_cases} | {errs.max():.1e} | {np.percentile(errs, 99):.1e} | {(errs > 1e-6).sum()} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=300, help="frames per pad size (default 300)")
    ap.add_argument("--sizes", type=int, nargs="+", default=[16, 32, 64], help="pad sizes (default 16 32 64)")
    ap.add_argument("--grid", type=int, default=41, help="load grid points per axis (default 41)")
    ap.add_argument("--crosscheck", type=int, default=1000, help="brute-force cases at 16x16 (default 1000)")
    ap.add_argument("--seed", type=int, default=1, help="random seed")
    args = ap.parse_args()
    print_versions()
    rng = np.random.default_rng(args.seed)
    rows, agree = timing_table(args.sizes, args.frames, rng)
    print_timing(rows, agree)
    accuracy_table(args.grid)
    if args.crosscheck:
        crosscheck(args.crosscheck, rng)


if __name__ == "__main__":
    main()
