"""The onset band of each load's path and pressure spread (lib/onset_band.py, docs/math.md §3.4)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from slipstack.lib.errors import ConfigError
from slipstack.lib.material import Material, detector_thresholds, load_material, material_toml
from slipstack.lib.onset_band import OnsetBand, load_path, pressure_spread

SIGMA = 0.005
RUBBER = Material("rubber", mu_s=0.45, mu_d=0.36, beta_s_m=1.3e-3, beta_d_m=1.07e-3, gamma_noise_stick=SIGMA,
                  gamma_noise_slide=SIGMA,
                  # a pull on a flat pad, three twists of a curved tip, a force off its centre
                  onset_gamma=(0.99, 0.95, 0.97, 0.96, 0.81),
                  onset_path=(0.02, 0.99, 1.0, 0.99, 0.34),
                  onset_spread=(0.05, 0.38, 0.38, 0.37, 0.39))


def test_load_path_by_hand() -> None:
    assert load_path(0.45, 0.0, 0.45, 1.3e-3) == 0.0
    assert load_path(0.0, -1.3e-3, 0.45, 1.3e-3) == 1.0
    # |f_t|/mu_s = 1 N, |tau|/beta_s = 1 N: half and half
    assert load_path(0.45, 1.3e-3, 0.45, 1.3e-3) == pytest.approx(0.5)
    assert math.isnan(load_path(0.0, 0.0, 0.45, 1.3e-3))     # no load
    assert math.isnan(load_path(1.0, 0.0, 0.45, math.nan))    # no beta_s


def test_pressure_spread_by_hand() -> None:
    assert pressure_spread(np.full(256, 0.02)) == 0.0
    # two levels 1 and 3 on the pressed taxels (and untouched ones): mean 2, std 1
    assert pressure_spread(np.array([1.0, 3.0, 0.0, 0.05])) == pytest.approx(0.5)
    assert math.isnan(pressure_spread(np.zeros(0)))
    assert math.isnan(pressure_spread(np.zeros(4)))


def test_each_kind_of_load_gets_the_bound_of_its_own_onsets() -> None:
    band = OnsetBand.of(RUBBER)
    pull, twist, off_centre = (1.0 - band.delta(p, k) for p, k in ((0.0, 0.05), (1.0, 0.38), (0.35, 0.38)))
    assert pull == pytest.approx(0.99 - 3 * SIGMA)                 # one onset: less its noise
    assert twist == pytest.approx(0.95 - 0.02 / 4 - 3 * SIGMA)      # three: the prediction bound
    assert off_centre == pytest.approx(0.81 - 3 * SIGMA)
    lowest = 1.0 - detector_thresholds(RUBBER).delta
    assert lowest == pytest.approx(0.81 - 0.18 / 6 - 3 * SIGMA)
    # Where no onset of the load's kind was identified, the wider of the lowest and the worst
    # case (here the lowest): a pull on a curved tip, a path between the identified ones, a
    # load without a pressure frame or without a load.
    for path, spread in ((0.0, 0.4), (0.6, 0.38), (0.0, math.nan), (math.nan, 0.05)):
        assert 1.0 - band.delta(path, spread) == pytest.approx(lowest)
        assert band.kind_of(path, spread) is None
    assert band.kind_of(0.9, 0.36).count == 3  # the twists' kind (path 0.993, spread 0.377)
    # the load itself: 0.4 N and 0.1 mN·m is a pull (path 0.03)
    assert band.delta_of_load(np.array([0.4, 0.0]), 1e-7, 0.06) == band.delta(0.0, 0.05)


def test_a_load_path_no_onset_covers_gets_the_worst_case_not_the_other_paths_onsets() -> None:
    # a file identified from a pull and a twist only (docs/materials.md's two ramps): a
    # combined load lets go lower than either (fig15 dropped its object with their band)
    pure = Material("pure", mu_s=0.45, mu_d=0.36, beta_s_m=1.3e-3, gamma_noise_stick=SIGMA,
                    onset_gamma=(0.99, 0.97), onset_path=(0.0, 1.0), onset_spread=(0.05, 0.05))
    band = OnsetBand.of(pure)
    assert 1.0 - band.delta(0.0, 0.05) == pytest.approx(0.99 - 3 * SIGMA)
    assert 1.0 - band.delta(0.5, 0.05) == pytest.approx(0.36 / 0.45 - 3 * SIGMA)  # the sliding level
    assert 1.0 - band.delta(0.0, 0.4) == pytest.approx(0.36 / 0.45 - 3 * SIGMA)


def test_a_file_without_paths_has_one_band_for_every_load() -> None:
    old = Material("old", mu_s=0.45, mu_d=0.36, onset_gamma=(0.99, 0.81), gamma_noise_stick=SIGMA)
    band = OnsetBand.of(old)
    assert band.kinds == ()
    assert band.delta(0.0, 0.05) == band.delta(1.0, 0.38) == detector_thresholds(old).delta


def test_onset_paths_round_trip_and_are_checked(tmp_path: Path) -> None:
    path = tmp_path / "m.toml"
    path.write_text(material_toml(RUBBER))
    read = load_material(path)
    assert (read.onset_gamma, read.onset_path, read.onset_spread) == (
        RUBBER.onset_gamma, RUBBER.onset_path, RUBBER.onset_spread)
    with pytest.raises(ConfigError, match="onset_path needs one entry per onset_gamma"):
        Material("x", mu_s=0.45, mu_d=0.36, onset_gamma=(0.9, 0.8), onset_path=(0.1,))
    with pytest.raises(ConfigError, match="onset_spread entries"):
        Material("x", mu_s=0.45, mu_d=0.36, onset_gamma=(0.9,), onset_path=(0.1,), onset_spread=(-1.0,))
    text = path.read_text().replace("onset_path = [", "onset_path = [true, ")
    path.write_text(text)
    with pytest.raises(ConfigError, match="material.onset_path: must be a list of numbers"):
        load_material(path)
