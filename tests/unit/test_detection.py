"""The slip latch: onset band, latching through the static->dynamic drop, release."""

import math

import pytest

from slipstack.lib.detection import DetectorConfig, SlipLatch
from slipstack.lib.errors import ConfigError

MS = 1_000_000


def test_onset_latch_and_release_by_hand():
    latch = SlipLatch(DetectorConfig(delta=0.05, gamma_release=0.6, release_ns=10 * MS))
    assert latch.update(0, 0.5) is False          # gamma 0.5: stick
    assert latch.update(1 * MS, 0.04) is True     # gamma 0.96 >= 0.95: slip
    assert latch.update(2 * MS, 0.22) is True     # sliding, gamma ~ mu_d/mu_s = 0.78: latched
    assert latch.update(3 * MS, 0.5) is True      # gamma 0.5 < 0.6: release timer starts
    assert latch.update(12 * MS, 0.5) is True     # 9 ms below: still latched
    assert latch.update(13 * MS, 0.5) is False    # 10 ms below: released


def test_nan_keeps_state_and_no_contact_clears():
    latch = SlipLatch()
    latch.update(0, 0.0)
    assert latch.update(1, math.nan) is True
    assert latch.update(2, 0.9, in_contact=False) is False


def test_bad_config_says_what_to_fix():
    with pytest.raises(ConfigError, match="gamma_release"):
        DetectorConfig(delta=0.1, gamma_release=0.95)
