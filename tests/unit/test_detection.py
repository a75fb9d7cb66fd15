"""The slip latch: onset band, latching through the static->dynamic drop, release."""

import math

import pytest

from slipstack.lib.detection import DetectorConfig, SlipLatch
from slipstack.lib.errors import ConfigError

MS = 1_000_000
ONE_FRAME = DetectorConfig(onset_frames=1)
"""The latch's defaults, but one frame in the band raises the flag (the tests of the latch
and its release below; the two-frame onset has its own test)."""


def test_onset_latch_and_release_by_hand():
    latch = SlipLatch(DetectorConfig(delta=0.05, gamma_release=0.6, release_ns=10 * MS, onset_frames=1))
    assert latch.update(0, 0.5) is False          # gamma 0.5: stick
    assert latch.update(1 * MS, 0.04) is True     # gamma 0.96 >= 0.95: slip
    assert latch.update(2 * MS, 0.22) is True     # sliding, gamma ~ mu_d/mu_s = 0.78: latched
    assert latch.update(3 * MS, 0.5) is True      # gamma 0.5 < 0.6: release timer starts
    assert latch.update(12 * MS, 0.5) is True     # 9 ms below: still latched
    assert latch.update(13 * MS, 0.5) is False    # 10 ms below: released


def test_nan_keeps_state_and_no_contact_clears():
    latch = SlipLatch(ONE_FRAME)
    latch.update(0, 0.0)
    assert latch.update(1, math.nan) is True
    assert latch.update(2, 0.9, in_contact=False) is False


def test_bad_config_says_what_to_fix():
    with pytest.raises(ConfigError, match="gamma_release"):
        DetectorConfig(delta=0.1, gamma_release=1.2)
    with pytest.raises(ConfigError, match="delta"):
        DetectorConfig(delta=1.0)


def test_release_level_above_the_band_acts_as_the_band_edge():
    # delta 0.25 (band edge 0.75) with the default release level 0.76: gamma 0.755 is
    # in the band (flagged), 0.745 is below both and releases after the dwell.
    latch = SlipLatch(DetectorConfig(delta=0.25, onset_frames=1))
    assert latch.update(0, 0.0) is True
    assert latch.update(10 * MS, 1.0 - 0.755) is True
    assert latch.update(12 * MS, 1.0 - 0.745) is True    # below from 12 ms
    assert latch.update(31 * MS, 1.0 - 0.745) is True    # 19 ms
    assert latch.update(32 * MS, 1.0 - 0.745) is False   # 20 ms: released


def test_default_release_sits_just_under_the_kinetic_floor():
    # Shipped rubber: mu_d/mu_s = 0.36/0.45 = 0.80; sliding keeps gamma at or above it
    # (noise sigma ~0.01), so the default latch holds there and lets go below 0.76.
    cfg = ONE_FRAME
    assert cfg.gamma_release == pytest.approx(0.36 / 0.45 - 0.04)
    latch = SlipLatch(cfg)
    assert latch.update(0, 0.17) is True                # gamma 0.83 >= 1 - 0.18: slip
    for k, gamma in enumerate([0.80, 0.79, 0.81, 0.78, 0.77, 0.80], start=1):
        assert latch.update(k * MS, 1.0 - gamma) is True  # sliding at the floor: held


def test_dip_below_the_floor_shorter_than_the_dwell_keeps_slip():
    # A fast stick-slip jump decelerates below the floor for < 20 ms while still sliding.
    latch = SlipLatch(ONE_FRAME)
    latch.update(0, 0.0)                                 # gamma 1.0: slip
    assert latch.update(2 * MS, 1.0 - 0.70) is True      # below 0.76: timer starts at 2 ms
    assert latch.update(20 * MS, 1.0 - 0.72) is True     # 18 ms below: still latched
    assert latch.update(21 * MS, 1.0 - 0.78) is True     # back above: timer reset
    assert latch.update(40 * MS, 1.0 - 0.75) is True     # below again from 40 ms
    assert latch.update(59 * MS, 1.0 - 0.75) is True     # 19 ms below
    assert latch.update(60 * MS, 1.0 - 0.75) is False    # 20 ms below: re-stuck, released


def test_restuck_load_just_under_the_floor_releases_after_the_dwell():
    # After re-sticking the load eases off from the sliding level 0.80 at 0.5 /s
    # (the default scene's ramp-down): gamma passes 0.76 at 80 ms, release 20 ms later.
    latch = SlipLatch(ONE_FRAME)
    latch.update(0, 0.0)
    verdicts = {t: latch.update(t * MS, 1.0 - (0.80 - 0.5 * t / 1000)) for t in range(1, 120, 2)}
    assert verdicts[79] is True                          # gamma 0.7605: at the floor, held
    assert verdicts[99] is True                          # below since 81 ms: 18 ms
    assert verdicts[101] is False                        # 20 ms below: released


def test_config_boundaries_are_accepted_and_just_outside_rejected():
    # The documented ranges: delta in [0, 1), gamma_release in (0, 1], release_ns >= 0.
    assert DetectorConfig(delta=0.0).delta == 0.0
    assert DetectorConfig(gamma_release=1.0).gamma_release == 1.0
    assert DetectorConfig(release_ns=0).release_ns == 0
    with pytest.raises(ConfigError, match="gamma_release"):
        DetectorConfig(gamma_release=0.0)
    with pytest.raises(ConfigError, match="release_ns"):
        DetectorConfig(release_ns=-1)
    with pytest.raises(ConfigError, match="delta"):
        DetectorConfig(delta=-1e-9)


def test_margin_exactly_at_the_band_edge_is_slip():
    # margin 1 - gamma <= delta flags slip; 0.25 is exact in binary, so this is the edge itself.
    latch = SlipLatch(DetectorConfig(delta=0.25, gamma_release=0.5, onset_frames=1))
    assert latch.update(0, 0.25) is True
    assert SlipLatch(DetectorConfig(delta=0.25, gamma_release=0.5, onset_frames=1)).update(0, 0.25 + 1e-12) is False


def test_gamma_exactly_at_the_release_level_holds_the_latch():
    # gamma >= gamma_release holds: 1 - 0.25 = 0.75 exactly, held far beyond the dwell.
    latch = SlipLatch(DetectorConfig(delta=0.125, gamma_release=0.75, release_ns=10 * MS, onset_frames=1))
    assert latch.update(0, 0.0) is True
    assert all(latch.update(t * MS, 0.25) for t in range(1, 100, 5))
    assert latch.update(101 * MS, 0.25 + 1e-12) is True    # just below: the dwell starts here
    assert latch.update(111 * MS, 0.25 + 1e-12) is False   # 10 ms below: released


def test_nan_margins_for_longer_than_the_dwell_keep_a_latched_slip():
    # No verdict (NaN) is no information: however long it lasts it neither starts nor
    # runs the release timer, so the grip law keeps seeing slip; a NaN inside the dwell
    # restarts it (release needs 20 ms of valid stick frames in a row).
    latch = SlipLatch(DetectorConfig(release_ns=20 * MS, onset_frames=1))
    assert latch.update(0, 0.0) is True
    assert all(latch.update(t * MS, math.nan) is True for t in range(1, 60, 3))
    assert latch.update(60 * MS, 0.5) is True               # a real stick frame starts the dwell
    assert latch.update(75 * MS, math.nan) is True          # no information: the dwell starts again
    assert latch.update(80 * MS, 0.5) is True               # the dwell restarts here
    assert latch.update(99 * MS, 0.5) is True
    assert latch.update(100 * MS, 0.5) is False             # 20 ms of valid stick frames: released
    # and a NaN keeps "stick" too
    stick = SlipLatch(ONE_FRAME)
    assert stick.update(0, 0.5) is False
    assert stick.update(1 * MS, math.nan) is False


def test_losing_contact_clears_the_latch_for_the_next_contact():
    latch = SlipLatch(DetectorConfig(release_ns=20 * MS, onset_frames=1))
    assert latch.update(0, 0.0) is True
    assert latch.update(1 * MS, 0.0, in_contact=False) is False
    assert latch.slipping is False
    assert latch.update(2 * MS, 0.5) is False               # a new contact that sticks: no old latch


def test_frames_between_release_and_resume_levels_do_not_restart_the_dwell():
    # Release level 0.58, resume level 0.59: 0.585 (above the level by noise alone) keeps
    # the dwell running, 0.595 restarts it.
    latch = SlipLatch(DetectorConfig(delta=0.4, gamma_release=0.58, release_ns=20 * MS, gamma_resume=0.59,
                                     onset_frames=1))
    assert latch.update(0, 0.0) is True
    assert latch.update(2 * MS, 1.0 - 0.585) is True    # above the level, dwell not started
    assert latch.update(4 * MS, 1.0 - 0.57) is True     # below: dwell starts at 4 ms
    assert latch.update(10 * MS, 1.0 - 0.585) is True   # noise above the level: dwell runs on
    assert latch.update(23 * MS, 1.0 - 0.57) is True    # 19 ms
    assert latch.update(24 * MS, 1.0 - 0.585) is False  # 20 ms: released on a frame between the levels
    latch = SlipLatch(DetectorConfig(delta=0.4, gamma_release=0.58, release_ns=20 * MS, gamma_resume=0.59,
                                     onset_frames=1))
    latch.update(0, 0.0)
    latch.update(4 * MS, 1.0 - 0.57)                    # dwell starts
    assert latch.update(10 * MS, 1.0 - 0.595) is True   # at/above resume: still sliding, dwell restarts
    assert latch.update(24 * MS, 1.0 - 0.57) is True    # dwell starts again at 24 ms
    assert latch.update(43 * MS, 1.0 - 0.57) is True
    assert latch.update(44 * MS, 1.0 - 0.57) is False


def test_resume_level_below_the_release_level_acts_as_the_release_level():
    cfg = DetectorConfig(delta=0.2, gamma_release=0.7, gamma_resume=0.65)
    assert cfg.resume_level == 0.7
    assert DetectorConfig(gamma_release=0.7).resume_level == 0.7       # NaN: the release level
    with pytest.raises(ConfigError, match="gamma_resume"):
        DetectorConfig(gamma_resume=1.5)


def test_noisy_load_falling_through_the_release_level_is_let_go_within_two_dwells():
    # A re-stuck load 0.6 sigma under the release level (sigma 0.01, 500 Hz frames):
    # about 27 % of the frames read above the level. With the resume level 2 sigma
    # above it the latch lets go one dwell after the load is below; restarting on every
    # frame above the level would need 10 frames in a row below it (p ~ 0.04 per try).
    import numpy as np

    rng = np.random.default_rng(7)
    release, sigma = 0.58, 0.01
    holds = []
    for _ in range(50):
        latch = SlipLatch(DetectorConfig(delta=0.4, gamma_release=release, release_ns=20 * MS,
                                         gamma_resume=release + 2 * sigma, onset_frames=1))
        latch.update(0, 0.0)
        t = 0
        while latch.slipping and t < 1000 * MS:
            t += 2 * MS
            latch.update(t, 1.0 - (release - 0.6 * sigma + sigma * rng.standard_normal()))
        holds.append(t / MS)
    assert max(holds) <= 40.0


def test_two_frames_in_a_row_in_the_band_raise_the_flag_by_default():
    # A load held 3.4 sigma under the band's edge reads in the band on single frames
    # (hold_force_coulomb: 1 frame in 1700): one such frame is not slip, two in a row are.
    latch = SlipLatch(DetectorConfig(delta=0.033, gamma_release=0.966))
    assert latch.config.onset_frames == 2
    assert latch.update(0, 1.0 - 0.950) is False
    assert latch.update(2 * MS, 1.0 - 0.968) is False    # one frame in the band: no flag
    assert latch.update(4 * MS, 1.0 - 0.952) is False    # out again: the row is broken
    assert latch.update(6 * MS, 1.0 - 0.970) is False
    assert latch.update(8 * MS, math.nan) is False       # no verdict: neither counts nor breaks the row
    assert latch.update(10 * MS, 1.0 - 0.975) is True    # second valid frame in a row: slip
    assert latch.update(12 * MS, 1.0 - 0.990) is True
    latch.update(14 * MS, 0.5, in_contact=False)         # lost contact clears the row too
    assert latch.update(16 * MS, 1.0 - 0.975) is False
    with pytest.raises(ConfigError, match="onset_frames"):
        DetectorConfig(onset_frames=0)


def test_exact_levels_with_a_resume_margin():
    # Release 0.625, resume 0.75 (exact in binary). A frame exactly at the release level
    # does not start the dwell; one exactly at the resume level restarts it.
    cfg = DetectorConfig(delta=0.125, gamma_release=0.625, release_ns=10 * MS, gamma_resume=0.75, onset_frames=1)
    latch = SlipLatch(cfg)
    assert latch.update(0, 0.0) is True
    assert all(latch.update(t * MS, 1.0 - 0.625) for t in range(1, 40, 3))   # at the level: held
    latch = SlipLatch(cfg)
    latch.update(0, 0.0)
    assert latch.update(1 * MS, 1.0 - 0.5) is True       # below: dwell starts at 1 ms
    assert latch.update(10 * MS, 1.0 - 0.75) is True     # exactly at resume: dwell restarts
    assert latch.update(11 * MS, 1.0 - 0.5) is True      # starts again at 11 ms
    assert latch.update(20 * MS, 1.0 - 0.5) is True      # 9 ms
    assert latch.update(21 * MS, 1.0 - 0.5) is False     # 10 ms: released


def test_a_fresh_latch_needs_two_frames_in_the_band_and_resume_bounds():
    latch = SlipLatch(DetectorConfig(delta=0.05))
    assert latch.update(0, 0.01) is False                # the very first frame, in the band
    assert latch.update(1 * MS, 0.01) is True
    assert DetectorConfig(gamma_resume=1.0).resume_level == 1.0
    with pytest.raises(ConfigError, match="gamma_resume"):
        DetectorConfig(gamma_resume=0.0)


STUCK = DetectorConfig(delta=0.03, gamma_release=0.76, onset_frames=1, sliding_level=0.8, stuck_margin=0.024)
"""A rubber-like contact (sliding level 0.8, noise margin 4 x 0.006) whose band for this
load path starts at 0.97 (a pull on a flat face lets go at 1)."""


def test_a_load_above_the_sliding_level_after_the_slip_reached_it_releases_after_the_dwell():
    # Sliding transmits only the sliding friction: once the slip brought gamma to the level,
    # a load held 0.9 > 0.8 + 0.024 for the dwell is a stuck contact (docs/math.md 3.1).
    latch = SlipLatch(STUCK)
    assert latch.update(0, 0.0) is True                  # onset at gamma 1
    for k, gamma in enumerate([0.95, 0.9, 0.85, 0.81, 0.80], start=1):
        assert latch.update(k * MS, 1.0 - gamma) is True  # the static->dynamic drop: held
    assert latch.update(10 * MS, 1.0 - 0.90) is True     # re-stuck: 0.9 from 10 ms
    assert latch.update(29 * MS, 1.0 - 0.90) is True     # 19 ms above
    assert latch.update(30 * MS, 1.0 - 0.90) is False    # 20 ms: released
    assert latch.update(31 * MS, 1.0 - 0.96) is False    # below the band: stays down
    assert latch.update(32 * MS, 1.0 - 0.975) is True    # in the band again: the next onset


def test_the_drop_after_an_onset_never_releases_however_slow():
    # A slow static->dynamic drop stays above the stuck level for longer than the dwell:
    # the slip has not reached the sliding level yet, so nothing is proven.
    latch = SlipLatch(STUCK)
    assert latch.update(0, 0.0) is True
    for k in range(1, 200):
        gamma = 0.96 - 0.15 * k / 200                    # 0.96 -> 0.81 over 200 ms
        assert latch.update(k * MS, 1.0 - gamma) is True


def test_a_frame_at_the_sliding_level_or_without_a_verdict_restarts_the_stuck_dwell():
    latch = SlipLatch(STUCK)
    latch.update(0, 0.0)
    latch.update(1 * MS, 0.2)                            # reached the level
    latch.update(2 * MS, 0.1)                            # 0.9: dwell from 2 ms
    latch.update(15 * MS, 0.2)                           # back at the level: restarts
    latch.update(16 * MS, 0.1)
    assert latch.update(35 * MS, 0.1) is True            # 19 ms since 16
    latch.update(36 * MS, math.nan)                      # no verdict: restarts
    assert latch.update(37 * MS, 0.1) is True
    assert latch.update(56 * MS, 0.1) is True
    assert latch.update(57 * MS, 0.1) is False


def test_a_coulomb_contact_is_never_released_by_the_stuck_rule():
    # mu_d = mu_s: the sliding level is 1, the stuck level above the band: only the release
    # level below it lets go.
    latch = SlipLatch(DetectorConfig(delta=0.045, gamma_release=0.955, onset_frames=1, sliding_level=1.0,
                                     stuck_margin=0.025))
    assert latch.update(0, 0.0) is True
    for k in range(1, 100):
        assert latch.update(k * MS, 1.0 - (0.96 if k % 2 else 0.99)) is True


def test_stuck_release_config_is_checked():
    with pytest.raises(ConfigError, match="sliding_level"):
        DetectorConfig(sliding_level=1.2, stuck_margin=0.02)
    with pytest.raises(ConfigError, match="stuck_margin"):
        DetectorConfig(sliding_level=0.8, stuck_margin=-0.01)
    assert DetectorConfig().stuck_level == math.inf
