"""Taxel pooling as a speed/accuracy knob: the exact test on a 16×16 pad summed into
2×2 and 4×4 blocks (``PadGeometry.pool``, the ``pool`` parameter of slip_detector and
cor_estimator), against the full resolution.

More in docs/modules.md, `tests/bench/bench_pooling.py`.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from slipstack.lib.limit_set import load_factor
from slipstack.lib.pad import PadGeometry
from _versions import print_versions

MU = 0.45
PAD = PadGeometry()


def fields() -> dict[str, np.ndarray]:
    """Normal force per taxel (N, Σ = 5 N) of four pressure fields on the 16×16 pad."""
    p = PAD.positions
    r = np.hypot(p[:, 0], p[:, 1])
    out = {
        "uniform disc r=7 mm": (r <= 7e-3).astype(float),
        "hertz a=6 mm": np.sqrt(np.clip(1 - (r / 6e-3) ** 2, 0, None)),
        "off-centre tilted": np.where((np.abs(p[:, 0] - 3e-3) <= 5e-3) & (np.abs(p[:, 1] + 2e-3) <= 5e-3),
                                      1.0 + 100.0 * (p[:, 0] - 3e-3 + 5e-3), 0.0),
        "two patches": ((np.hypot(p[:, 0] + 5e-3, p[:, 1]) <= 3e-3) | (np.hypot(p[:, 0] - 5e-3, p[:, 1]) <= 3e-3)).astype(float),
    }
    return {k: 5.0 * v / v.sum() for k, v in out.items()}


def loads(phi: np.ndarray, n: int, rng: np.random.Generator) -> list[tuple[np.ndarray, float, float]]:
    """(f_t, τ, γ_full) with γ_full uniform in [0.5, 1.5]."""
    out = []
    while len(out) < n:
        d = rng.normal(size=3)
        f_t, tau = d[:2] * MU * 5.0, d[2] * MU * 5.0 * 4e-3
        g = load_factor(phi, PAD.positions, f_t, tau, MU).gamma
        if not np.isfinite(g) or g <= 0:
            continue
        k = rng.uniform(0.5, 1.5) / g
        g2 = load_factor(phi, PAD.positions, f_t * k, tau * k, MU).gamma
        out.append((f_t * k, tau * k, g2))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--loads", type=int, default=400, help="loads per field (default 400)")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    print_versions()
    rng = np.random.default_rng(args.seed)
    print("| field | pool | taxels | p50 µs | p99 µs | γ err p95 | γ err worst | false stick | false slip |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    for name, phi in fields().items():
        cases = loads(phi, args.loads, rng)
        for block in (1, 2, 4):
            pad = PAD.pooled(block) if block > 1 else PAD
            ph = PAD.pool(phi, block) if block > 1 else phi
            times, errs, fstick, fslip = [], [], 0, 0
            warm = None
            for f_t, tau, g_full in cases:
                t0 = time.perf_counter_ns()
                r = load_factor(ph, pad.positions, f_t, tau, MU, c0=warm)
                times.append(time.perf_counter_ns() - t0)
                warm = r.p_c
                errs.append(abs(r.gamma - g_full) / g_full)
                fstick += g_full > 1 and r.gamma <= 1
                fslip += g_full <= 1 and r.gamma > 1
            t = np.array(times) / 1e3
            e = np.array(errs)
            print(f"| {name} | {block}x{block} | {int(np.count_nonzero(ph))} | {np.percentile(t, 50):.0f} | "
                  f"{np.percentile(t, 99):.0f} | {np.percentile(e, 95):.2e} | {e.max():.2e} | "
                  f"{100 * fstick / len(cases):.1f}% | {100 * fslip / len(cases):.1f}% |")


if __name__ == "__main__":
    main()
