"""The detector on a batch (a contact carrying earlier samples) equals the detector
stepped sample by sample: same latched state, kind and γ of the newest, same samples
examined, and so never a lost slip flag; and the onset counts in time, not samples."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from slipstack.lib.detector import Detector, DetectorSettings, PadContact
from slipstack.lib.status import SAMPLE_NO_CONTACT, SAMPLE_OK, SAMPLE_UNUSABLE

MU = 0.5
SETTINGS = {"mu": MU, "delta": 0.1, "gamma_release": 0.8, "release_ns": 3_000_000, "also": ()}
SHAPE = np.zeros(256)
SHAPE.reshape(16, 16)[4:10, 6:12] = np.linspace(0.5, 1.5, 36).reshape(6, 6)


@dataclass(frozen=True)
class _Batch(PadContact):
    """A PadContact (the newest sample) carrying earlier samples as the ``contact`` message does."""

    earlier_samples: int = 0
    earlier_stamp_ns: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    earlier_f_n: np.ndarray = field(default_factory=lambda: np.zeros(0))
    earlier_f_tx: np.ndarray = field(default_factory=lambda: np.zeros(0))
    earlier_f_ty: np.ndarray = field(default_factory=lambda: np.zeros(0))
    earlier_tau: np.ndarray = field(default_factory=lambda: np.zeros(0))
    earlier_status: np.ndarray = field(default_factory=lambda: np.zeros(0, np.uint8))


def _phi(f_n: float, tactile: bool) -> np.ndarray:
    return SHAPE * (f_n / SHAPE.sum()) if tactile else np.zeros(0)


def _single(sample: tuple, tactile: bool, phi_newest: np.ndarray | None) -> PadContact:
    """A sample as its own contact: the batch's pressure frame scaled to its normal force."""
    f_n, fx, fy, tau, status = sample
    if phi_newest is not None and phi_newest.sum() > 0:
        phi = phi_newest * (f_n / phi_newest.sum())
    else:
        phi = _phi(f_n, tactile)
    return PadContact(f_n=f_n, f_t=np.array([fx, fy]), tau=tau, phi=phi, status=status)


STATUSES = ("ok", "ok", "ok", "no_contact", "stale")
sample = st.tuples(
    st.floats(0.5, 10.0),  # f_n, N
    st.floats(-6.0, 6.0),  # f_x, N
    st.floats(-6.0, 6.0),  # f_y, N
    st.floats(-4e-3, 4e-3),  # τ, N·m
    st.sampled_from(STATUSES),  # the sample's own contact's status
)


def _code(status: str) -> int:
    return {"ok": SAMPLE_OK, "no_contact": SAMPLE_NO_CONTACT}.get(status, SAMPLE_UNUSABLE)
batches = st.lists(st.lists(sample, min_size=1, max_size=7), min_size=1, max_size=12)


@settings(max_examples=120, deadline=None)
@given(batches=batches, method=st.sampled_from(["exact", "coulomb", "tactile_cor"]), period_ns=st.sampled_from([143_000, 1_000_000]),
       noise=st.sampled_from([(math.nan, math.nan), (0.05, 1e-4)]))
def test_a_batch_is_judged_as_its_samples_one_by_one(batches, method, period_ns, noise):
    """... also with the noise guard (F/T noise 0.05 N, 0.1 mN·m: μ f_n under 0.5 N, f_n under 1 N,
    or β f_n under 1 mN·m is ``below_noise``)."""
    tactile = method != "coulomb"
    settings_ = DetectorSettings(**SETTINGS, method=method, beta_m=0.0 if tactile else 2e-3,
                                 force_noise_n=noise[0], torque_noise_nm=noise[1])
    by_batch, one_by_one = Detector(settings_), Detector(settings_)
    t, want_slipping = 0, False
    for batch in batches:
        stamps = [t + k * period_ns for k in range(len(batch))]
        t = stamps[-1] + period_ns
        f_n, fx, fy, tau, _ = batch[-1]
        newest_phi = _phi(f_n, tactile)
        newest = _single(batch[-1], tactile, None)
        earlier = batch[:-1]
        contact = _Batch(
            f_n=f_n, f_t=np.array([fx, fy]), tau=tau, phi=newest_phi, status=newest.status,
            earlier_samples=len(earlier), earlier_stamp_ns=np.array(stamps[:-1], np.int64),
            earlier_f_n=np.array([s[0] for s in earlier]), earlier_f_tx=np.array([s[1] for s in earlier]),
            earlier_f_ty=np.array([s[2] for s in earlier]), earlier_tau=np.array([s[3] for s in earlier]),
            earlier_status=np.array([_code(s[4]) for s in earlier], np.uint8))
        got = by_batch.step(contact, stamps[-1], tactile_frame=1)
        was_slipping, raised_at, lost_after = want_slipping, None, False
        for s, stamp in zip(earlier, stamps):
            v = one_by_one.step(_single(s, tactile, newest_phi), stamp, tactile_frame=1)
            if v.slipping and not was_slipping and raised_at is None:
                raised_at = stamp
            lost_after |= raised_at is not None and v.state == "no-contact"
            was_slipping = v.slipping
        want = one_by_one.step(newest, stamps[-1], tactile_frame=1)
        want_slipping = want.slipping
        assert (got.slipping, got.state, got.kind, got.status) == (want.slipping, want.state, want.kind, want.status)
        assert got.gamma == want.gamma or (math.isnan(got.gamma) and math.isnan(want.gamma))
        assert by_batch.samples_judged == one_by_one.samples_judged
        if raised_at is not None and not lost_after and want.state != "no-contact" \
                and stamps[-1] - raised_at < SETTINGS["release_ns"]:
            assert got.slipping, "a slip raised inside the batch was lost"


@pytest.mark.parametrize("period_ns", [1_000_000, 143_000])
def test_the_onset_takes_the_same_time_at_1_and_7_khz(period_ns):
    """A load held in the onset band raises the flag 0.9 ms (two 1 kHz frames) after it entered
    the band, at either rate; so one noisy 7 kHz sample pair never does."""
    det = Detector(DetectorSettings(**SETTINGS))
    at_limit = PadContact(f_n=5.0, f_t=np.array([0.99 * MU * 5.0, 0.0]), tau=0.0, phi=_phi(5.0, True))
    flagged_at = None
    for k in range(20):
        if det.step(at_limit, k * period_ns, tactile_frame=1).slipping:
            flagged_at = k * period_ns
            break
    assert flagged_at is not None and 900_000 <= flagged_at < 900_000 + period_ns
