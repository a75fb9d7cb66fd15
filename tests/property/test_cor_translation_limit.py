"""The COR solvers at the translational limit |f_t| = μ Σφ, to the last rounding step."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from slipstack.lib.cor import robust_cor
from slipstack.lib.pad import PadGeometry
from slipstack.lib.slip_tests import SlipParams, tactile_cor_robust

PAD = PadGeometry()


class _Contact:
    def __init__(self, phi, f_t, tau=0.0):
        self.phi, self.f_t, self.tau, self.positions = phi, np.asarray(f_t, float), tau, PAD.positions
        self.f_n = float(phi.sum())


def test_a_force_one_rounding_step_below_the_limit_is_not_read_as_no_load():
    # Found in a run: tactile_cor_robust called stick with margin 1 during pure-force slip.
    phi = np.full(256, 0.03906252812782039)
    r = robust_cor(phi, PAD.positions, (5.00000360036101, 0.0), 0.0, 0.5)
    assert r.status.value == "translation"
    assert r.ratio == math.hypot(5.00000360036101, 0.0) / (0.5 * phi.sum())  # 1 - 2e-16, not 0
    verdict = tactile_cor_robust(_Contact(phi, (5.00000360036101, 0.0)), SlipParams(mu=0.5, delta=0.05))
    assert verdict.margin < 1e-12 and not verdict.stick


@settings(max_examples=200, deadline=None)
@given(
    level=st.floats(1.0, 20.0),
    angle=st.floats(0.0, 2 * math.pi),
    ulps=st.integers(-4, 4),
    patch=st.integers(2, 16),
)
def test_the_ratio_stays_at_one_across_the_translational_limit(level, angle, ulps, patch):
    phi = np.zeros((16, 16))
    phi[:patch, :patch] = level / patch**2
    phi = phi.reshape(-1)
    mu = 0.45
    size = mu * phi.sum()
    for _ in range(abs(ulps)):
        size = math.nextafter(size, math.inf if ulps > 0 else 0.0)
    f_t = (size * math.cos(angle), size * math.sin(angle))
    r = robust_cor(phi, PAD.positions, f_t, 0.0, mu)
    assert r.status.usable
    # at the limit, whatever the rounding, never "no load": a step below it the Weber
    # minimum lies kilometres away, where the ratio carries ~1e-6 of cancellation
    assert abs(r.ratio - 1.0) < 1e-5, r
