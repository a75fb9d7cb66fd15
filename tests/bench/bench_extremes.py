"""Robustness sweep: random extreme frames through fusion and every slip test.

More in docs/modules.md, `tests/bench/bench_extremes.py`.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections import Counter

import numpy as np

from slipstack.lib.fusion import fuse
from slipstack.lib.pad import PadGeometry
from slipstack.lib.slip_tests import SLIP_TESTS, SlipParams
from slipstack.lib.status import SolverStatus
from _versions import print_versions

PADS = [PadGeometry(4, 4, 2e-3), PadGeometry(8, 8, 1.25e-3), PadGeometry(16, 16, 1.25e-3)]


def random_frame(rng):
    pad = PADS[rng.integers(len(PADS))]
    n = pad.n_taxels
    kind = rng.integers(6)
    if kind == 0:
        p = rng.random(n) * (rng.random(n) < 0.2)
    elif kind == 1:
        p = np.zeros(n)
        p[rng.integers(n)] = 1.0
    elif kind == 2:
        p = np.zeros(n)
    elif kind == 3:
        p = np.exp(4 * rng.normal(size=n))
    elif kind == 4:
        p = rng.random(n)
        bad = rng.random(n) < 0.1
        p[bad] = rng.choice([np.nan, np.inf, -np.inf, -1.0], size=int(bad.sum()))
    else:
        x, y = pad.positions.T
        p = np.clip(1 - ((x - rng.normal() * 3e-3) ** 2 + y**2) / (rng.random() * 8e-3 + 1e-4) ** 2, 0, None)
    scale = 10.0 ** rng.uniform(-9, 4)
    f_n = scale * rng.choice([1.0, 1.0, 1.0, 0.0, -0.5, 1e-300])
    load = rng.integers(6)
    mu = 0.5
    half = pad.rows * pad.pitch_m / 2
    if load == 0:
        f_t, tau = np.zeros(2), 0.0
    elif load == 1:
        f_t, tau = rng.normal(size=2) * scale, 0.0
    elif load == 2:
        f_t, tau = np.zeros(2), rng.normal() * scale * half
    elif load == 3:  # on the Coulomb boundary
        d = rng.normal(size=2)
        f_t, tau = d / np.linalg.norm(d) * mu * abs(f_n), rng.normal() * scale * half * 1e-6
    else:
        f_t, tau = rng.normal(size=2) * scale, rng.normal() * scale * half
    return pad, p, np.array([f_t[0], f_t[1], -f_n]), np.array([0.0, 0.0, tau])


def check(v) -> str | None:
    if not isinstance(v.status, SolverStatus):
        return "missing status"
    for name in ("margin", "gamma"):
        x = getattr(v, name)
        if math.isnan(x):
            return f"NaN {name}"
        if math.isinf(x) and v.status is not SolverStatus.POINT_CONTACT:
            return f"undocumented inf {name}"
    if v.p_c is not None and not all(math.isfinite(c) for c in v.p_c):
        return "non-finite p_c"
    return None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=100_000, help="number of random frames (default 1e5)")
    ap.add_argument("--seed", type=int, default=7, help="random seed")
    args = ap.parse_args()
    print_versions()
    rng = np.random.default_rng(args.seed)
    params = SlipParams(mu=0.5)
    failures: Counter = Counter()
    statuses: Counter = Counter()
    examples = []
    step = max(1, args.frames // 20)
    for k in range(args.frames):
        pad, p, force, torque = random_frame(rng)
        try:
            fr = fuse(p, force, torque, pad)
            statuses[("fusion", fr.status.value)] += 1
            prev = None
            for name, test in SLIP_TESTS.items():
                v = test(fr, params, prev if name == "exact" else None)
                statuses[(name, v.status.value)] += 1
                why = check(v)
                if why:
                    failures[(name, why)] += 1
                    if len(examples) < 5:
                        examples.append((k, name, why, v))
        except Exception as exc:  # noqa: BLE001 - counting is the point
            failures[("exception", type(exc).__name__)] += 1
            if len(examples) < 5:
                examples.append((k, "exception", repr(exc), None))
        if (k + 1) % step == 0:
            print(f"... {k + 1}/{args.frames} frames, failures so far {sum(failures.values())}",
                  file=sys.stderr, flush=True)
    print(f"## Extreme frames: {args.frames} random frames, seed {args.seed}\n")
    print(f"**failures: {sum(failures.values())}**\n")
    if failures:
        print("| where | failure | count |\n| --- | --- | ---: |")
        for (where, why), c in failures.most_common():
            print(f"| {where} | {why} | {c} |")
        for ex in examples:
            print(ex)
    print("\n| method | status | count |\n| --- | --- | ---: |")
    for (name, st), c in sorted(statuses.items()):
        print(f"| {name} | {st} | {c} |")


if __name__ == "__main__":
    main()
