"""The tactile array's mounting on the pad: flips and quarter turns, checked by hand."""

from __future__ import annotations

import numpy as np
import pytest

from slipstack.lib.errors import ConfigError
from slipstack.lib.pad import PadGeometry, PadMount


def _position_of_marked_taxel(image: np.ndarray, pitch: float = 1.0) -> np.ndarray:
    pad = PadGeometry(*image.shape, pitch)
    return pad.positions[int(np.argmax(image.reshape(-1)))]


def test_a_quarter_turn_moves_x_y_to_minus_y_x():
    image = np.zeros((3, 5))
    image[0, 4] = 1.0  # row 0 (y = -1), col 4 (x = +2): at (2, -1)
    assert _position_of_marked_taxel(image) == pytest.approx((2.0, -1.0))
    turned = PadMount(quarter_turns=1).apply(image)
    assert turned.shape == (5, 3) == PadMount(quarter_turns=1).shape(3, 5)
    assert _position_of_marked_taxel(turned) == pytest.approx((1.0, 2.0))  # (-y, x)
    half = PadMount(quarter_turns=2).apply(image)
    assert _position_of_marked_taxel(half) == pytest.approx((-2.0, 1.0))
    three = PadMount(quarter_turns=3).apply(image)
    assert _position_of_marked_taxel(three) == pytest.approx((-1.0, -2.0))


def test_flips_mirror_along_y_and_x():
    image = np.zeros((3, 5))
    image[0, 4] = 1.0  # (2, -1)
    assert _position_of_marked_taxel(PadMount(flip_rows=True).apply(image)) == pytest.approx((2.0, 1.0))
    assert _position_of_marked_taxel(PadMount(flip_cols=True).apply(image)) == pytest.approx((-2.0, -1.0))
    both = PadMount(flip_rows=True, flip_cols=True).apply(image)
    assert np.array_equal(both, PadMount(quarter_turns=2).apply(image))  # two mirrors = a half turn


def test_identity_and_bad_turns():
    image = np.arange(6).reshape(2, 3)
    assert PadMount().identity and np.array_equal(PadMount().apply(image), image)
    with pytest.raises(ConfigError, match="quarter_turns"):
        PadMount(quarter_turns=4)
