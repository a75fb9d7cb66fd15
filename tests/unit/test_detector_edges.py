"""The library detector's defaults and its β for the F/T tests, checked by hand.

The F/T tests (5)–(7) need a torsional coefficient β. With ``beta_m`` set, that β is
used whatever the pressure; with ``beta_m = 0`` it is β_s of each pressure frame. For a
pure torque the linear surface (5) gives γ = |τ| / (β f_n), so γ tells which β was used.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from slipstack.lib.detector import Detector, DetectorSettings, PadContact
from slipstack.lib.errors import ConfigError
from slipstack.lib.limit_set import torsional_coefficient
from slipstack.lib.pad import PadGeometry

MU = 0.45
F_N = 10.0
TAU = 0.01  # N·m


def _twisted(**pad: object) -> PadContact:
    phi = np.full(256, F_N / 256)
    return PadContact(f_n=F_N, f_t=np.zeros(2), tau=TAU, phi=phi, **pad)


def test_a_pad_contact_defaults_to_the_shipped_16_by_16_pad_of_1_25_mm():
    c = _twisted()
    assert (c.rows, c.cols, c.pitch_m, c.has_tactile, c.tactile_status) == (16, 16, 1.25e-3, True, "ok")
    one = PadContact(f_n=1.0, f_t=np.zeros(2), tau=0.0, phi=np.ones(1), rows=1, cols=1)
    assert one.has_tactile  # a single taxel is a pressure frame too
    assert PadContact(f_n=1.0, f_t=np.zeros(2), tau=0.0).tactile_status == "none"


def test_beta_from_the_pressure_frame_when_none_is_configured():
    beta_s = torsional_coefficient(np.full(256, F_N / 256), PadGeometry().positions, MU).beta_m
    det = Detector(DetectorSettings(mu=MU, delta=0.1, gamma_release=0.76, method="linear_ls", also=()))
    v = det.step(_twisted(), 0, tactile_frame=1)
    assert v.status == "ok"
    assert v.gamma == pytest.approx(TAU / (beta_s * F_N), rel=1e-9)


def test_a_configured_beta_wins_over_the_pressure_frames():
    det = Detector(DetectorSettings(mu=MU, delta=0.1, gamma_release=0.76, method="linear_ls", also=(),
                                    beta_m=2e-3))
    v = det.step(_twisted(), 0, tactile_frame=1)
    assert v.gamma == pytest.approx(TAU / (2e-3 * F_N), rel=1e-12)  # 0.5, not the frame's β_s


@pytest.mark.parametrize("beta", [-1e-3, math.nan, math.inf])
def test_beta_must_be_a_finite_length_of_zero_or_more(beta):
    with pytest.raises(ConfigError, match="beta_m"):
        DetectorSettings(mu=MU, delta=0.1, gamma_release=0.76, beta_m=beta)
