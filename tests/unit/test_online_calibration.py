"""Online calibration (docs/math.md §3.3): it learns from what the contact shows, and
nothing — a false alarm, noise, any stream of load factors — widens the band, lowers the
release level or μ, or moves μ past the loads seen (it cannot run away)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from slipstack.lib.detection import DetectorConfig
from slipstack.lib.material import Material, detector_thresholds
from slipstack.lib.online_calibration import CalibratedLatch, OnlineCalibration

MS = 1_000_000
DEFAULT = Material("default", mu_s=0.45, mu_d=0.36, gamma_noise_stick=0.005, gamma_noise_slide=0.005)
"""No onsets: the worst-case band, edge 0.8 − 0.015 = 0.785 (lib/material.py)."""


def _latch(material: Material = DEFAULT) -> CalibratedLatch:
    t = detector_thresholds(material)
    return CalibratedLatch(DetectorConfig(t.delta, t.gamma_release, gamma_resume=t.gamma_resume), material)


def _feed(latch: CalibratedLatch, gammas: np.ndarray, start_ms: int = 0) -> np.ndarray:
    return np.array([latch.update((start_ms + k) * MS, 1.0 - g)[0] for k, g in enumerate(gammas)])


def _episode(peak: float, level: float, rng: np.random.Generator) -> np.ndarray:
    """A ramp to ``peak`` in 500 ms, 200 ms sliding at ``level``, unload, 300 ms rest (1 ms frames)."""
    g = np.concatenate([np.linspace(0.0, peak, 500), np.full(200, level), np.linspace(level, 0.0, 100), np.zeros(300)])
    return g + rng.normal(0.0, 0.005, g.size)


def test_a_contact_grippier_than_the_default_raises_mu_to_what_it_carried_and_no_further() -> None:
    """A Coulomb object with μ 0.5 under the default's 0.45: it slides at γ 1.11 of the
    default. μ rises to about 0.5 (the rule's lower bound: mean − 3σ/√8), never past it."""
    latch = _latch()
    rng = np.random.default_rng(1)
    _feed(latch, _episode(0.5 / 0.45, 0.5 / 0.45, rng))
    cal = latch.calibration
    assert 0.5 / 0.45 * 0.99 < cal.learned.mu_scale <= 0.5 / 0.45 + 1e-9
    assert cal.learned.episodes == 1


def test_confirmed_slips_narrow_the_band_to_their_onsets_and_later_ones_are_caught() -> None:
    """Coulomb at the default's μ: every episode lets go at γ 1. After the first the band's
    edge moves from 0.785 up to under the onset; a later episode is still flagged before
    it lets go, and a 95 % hold no longer is."""
    latch = _latch()
    rng = np.random.default_rng(2)
    first = _feed(latch, _episode(1.0, 1.0, rng))
    assert first.any()
    learned = latch.calibration.learned
    assert 0.9 < 1.0 - learned.delta < 1.0 and learned.delta < detector_thresholds(DEFAULT).delta
    later = _feed(latch, _episode(1.0, 1.0, rng), start_ms=1100)
    assert later[480:700].any()  # flagged around the onset (500 ms)
    hold = _feed(latch, np.full(2000, 0.95) + rng.normal(0.0, 0.005, 2000), start_ms=2200)
    assert not hold.any()


def test_a_false_alarm_never_widens_the_band_nor_lowers_the_release() -> None:
    """A load held inside the default band (γ 0.85, never slips) is confirmed like a slip:
    it can only narrow the band to just under itself; the release level does not fall."""
    latch = _latch()
    start = latch.calibration.learned
    rng = np.random.default_rng(3)
    held = np.concatenate([np.linspace(0.0, 0.85, 300), np.full(1000, 0.85), np.linspace(0.85, 0.0, 200)])
    _feed(latch, held + rng.normal(0.0, 0.005, held.size))
    learned = latch.calibration.learned
    assert learned.episodes == 1 and learned.mu_scale == 1.0
    assert learned.delta <= start.delta and 1.0 - learned.delta <= 0.85
    assert learned.gamma_release >= start.gamma_release


@st.composite
def load_factors(draw) -> np.ndarray:
    """Noise, or stretches of drawn levels held for drawn times (sustained flags, false alarms,
    loads beyond 1), with NaN frames."""
    if draw(st.booleans()):
        return draw(hnp.arrays(float, st.integers(1, 3000), elements=st.floats(-0.5, 3.0) | st.just(math.nan)))
    parts = [np.full(draw(st.integers(1, 400)), draw(st.floats(-0.5, 3.0) | st.just(math.nan)))
             for _ in range(draw(st.integers(1, 12)))]
    return np.concatenate(parts)


@settings(max_examples=80, deadline=None)
@given(load_factors())
def test_it_cannot_run_away(gammas: np.ndarray) -> None:
    """Any stream: μ only rises, and never beyond the highest mean of 8 frames in a row
    (bounded by max_scale); the band only narrows, the release only rises."""
    latch = _latch()
    cal: OnlineCalibration = latch.calibration
    start = cal.learned
    previous = start
    for k, g in enumerate(gammas):
        latch.update(k * MS, 1.0 - g)
        now = cal.learned
        assert now.mu_scale >= previous.mu_scale and now.delta <= previous.delta
        assert now.gamma_release >= previous.gamma_release
        previous = now
    finite = np.where(np.isfinite(gammas), gammas, -np.inf)
    runs = np.convolve(finite, np.ones(8) / 8, mode="valid") if gammas.size >= 8 else np.array([1.0])
    highest = max(float(np.max(runs, initial=1.0)), 1.0)
    assert previous.mu_scale <= min(highest, cal.settings.max_scale) + 1e-9
    assert 0.0 <= previous.delta <= start.delta and previous.gamma_release <= 1.0 - previous.delta + 1e-12


def test_without_calibration_the_latch_is_the_plain_one() -> None:
    t = detector_thresholds(DEFAULT)
    latch = CalibratedLatch(DetectorConfig(t.delta, t.gamma_release))
    assert latch.calibration is None
    assert latch.update(0, 0.1) == (False, 0.1) and latch.update(MS, 0.1) == (True, pytest.approx(0.1))


def _slip(cal: OnlineCalibration, gammas: list[float], start_ms: int) -> None:
    """The latch's flag up for one frame per ms at ``gammas``, then down."""
    for k, g in enumerate(gammas):
        cal.step((start_ms + k) * MS, g, True)
    cal.step((start_ms + len(gammas)) * MS, 0.0, False)


def test_only_a_flag_up_for_the_confirm_time_is_an_episode() -> None:
    cal = OnlineCalibration(DEFAULT)
    start = cal.learned
    _slip(cal, [0.9] * 50, start_ms=0)  # up from 0 to 49 ms: 1 ms short of 50 ms
    assert cal.learned == start and cal.revision == 0
    _slip(cal, [0.9] * 51, start_ms=100)  # up for 50 ms
    assert cal.learned.episodes == 1


def test_an_episode_releases_at_the_sliding_level_of_its_second_half_less_its_noise() -> None:
    """Onset 1.0, then 0.9 and 0.97: the sliding level is the median of the run's second
    half (0.97, not 0.935 of its last two thirds); release 0.97 − 4σ, resume 0.97 − 2σ
    (σ = 0.005), both under the band's edge."""
    cal = OnlineCalibration(DEFAULT)
    _slip(cal, [1.0] * 20 + [0.9] * 20 + [0.97] * 20, start_ms=0)
    learned = cal.learned
    assert learned.episodes == 1
    assert learned.gamma_release == pytest.approx(0.95, abs=1e-12)
    assert learned.gamma_resume == pytest.approx(0.96, abs=1e-12) and learned.gamma_resume < 1.0 - learned.delta


def test_without_a_measured_noise_mu_rises_to_the_mean_less_3_sigma_of_0_002() -> None:
    cal = OnlineCalibration(Material("no noise measured", mu_s=0.45, mu_d=0.36))  # gamma_noise_stick NaN
    for k in range(8):
        cal.step(k * MS, 1.2, False)
    assert cal.learned.mu_scale == pytest.approx(1.2 - 3.0 * 0.002 / math.sqrt(8), abs=1e-12)


def test_an_identified_file_with_load_paths_calibrates_without_error() -> None:
    """`identify` writes each onset's load path and pressure spread; learning the first
    confirmed slip from such a file must not build a material whose lists disagree (it raised
    ConfigError there: onset_path 3 entries, onset_gamma 1)."""
    identified = Material("identified", mu_s=0.45, mu_d=0.36, gamma_noise_stick=0.005, gamma_noise_slide=0.005,
                          onset_gamma=(0.97, 0.98, 0.81), onset_path=(0.02, 0.99, 0.34),
                          onset_spread=(0.05, 0.38, 0.39))
    latch = _latch(identified)
    flags = _feed(latch, _episode(1.0, 0.8, np.random.default_rng(3)))
    assert flags.any()
    assert latch.calibration.learned.episodes == 1
