"""``lib.fusion.ft_understates_pad`` at its boundaries: the pad's force ``Σ p h²`` (N)
against ``ratio`` times the F/T normal force, on a pad whose numbers are exact in binary."""

from __future__ import annotations

import numpy as np
import pytest

from slipstack.lib.fusion import FusionThresholds, ft_understates_pad, pressure_shape
from slipstack.lib.pad import PadGeometry

PAD = PadGeometry(2, 2, 0.5)  # taxel area 0.25 m²
assert PAD.taxel_area_m2 == 0.25


def pad_pressed_with(force_n: float):
    """The shape of the four taxels pressed evenly with ``force_n`` N in all: ``force_n`` Pa
    on each, 4 × 0.25 m² × ``force_n`` Pa."""
    return pressure_shape(np.full(4, force_n), PAD, FusionThresholds())


@pytest.mark.parametrize(("ft_n", "ratio", "min_pad_n", "pad_n", "understated"), [
    (0.5, 2.0, 0.5, 1.0, False),   # F/T exactly pad / ratio: not under
    (0.49, 2.0, 0.5, 1.0, True),   # a little less: under
    (0.1, 3.0, 1.0, 1.0, False),   # the pad's force exactly at the minimum: not judged
    (0.1, 3.0, 0.99, 1.0, True),   # just above it: judged
    (0.6, 1.0, 0.5, 1.0, True),    # ratio 1: the F/T sensor must read the pad's whole force
    (0.0, 0.0, 0.5, 1.0, False),   # ratio 0: the check is off
])
def test_ft_understates_pad_at_its_boundaries(ft_n, ratio, min_pad_n, pad_n, understated):
    shape = pad_pressed_with(pad_n)
    assert shape.pressure_sum_pa * PAD.taxel_area_m2 == pad_n
    assert ft_understates_pad(shape, PAD, ft_n, ratio=ratio, min_pad_force_n=min_pad_n) is understated  # a bool
