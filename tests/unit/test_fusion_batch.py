"""fusion on a batch of F/T samples: one contact for the newest that carries every
earlier sample's load in the pad frame, oldest first, each judged usable as its own
contact would be, and the first unusable one's status when the newest is usable."""

from __future__ import annotations

import numpy as np
import pytest

from slipstack.messages import Contact, Header, TactileFrame, Wrench, decode, encode
from slipstack.messages.types import MAX_EARLIER_SAMPLES, SAMPLE_NO_CONTACT, SAMPLE_OK, SAMPLE_UNUSABLE
from slipstack.nodes.fusion import SAMPLES_PER_CONTACT, Fusion, FusionParams
from slipstack.nodes.runtime.inprocess import InProcessExecutor

MS = 1_000_000
PITCH_M = 1.25e-3


def _tactile(f_n: float, stamp: int) -> TactileFrame:
    p = np.zeros((16, 16), dtype=np.float32)
    p[5:11, 5:11] = f_n / (36 * PITCH_M**2)
    return TactileFrame(rows=16, cols=16, pitch_m=PITCH_M, pressure_pa=p.reshape(-1), saturated=np.zeros(256, bool),
                        dead=np.zeros(256, bool), header=Header(stamp, 0, stamp, {}))


def _wrench(k: int, f_n: float, f_x: float, tau: float, status: str = "ok") -> Wrench:
    stamp = 10 * MS + k * 143_000  # 7 kHz
    return Wrench(force=np.array([f_x, -0.5 * f_x, -f_n]), torque=np.array([0.1, 0.2, tau]), frame="pad",
                  device_seq=k + 1, status=status, header=Header(stamp, k, stamp, {}))


def _run(wrenches: list[Wrench], tactile: bool = True) -> tuple[list[Contact], InProcessExecutor]:
    """Feed one tactile frame, then every wrench at one instant (one wake-up's batch)."""
    ex = InProcessExecutor([Fusion(FusionParams(use_tactile=tactile))], keep_published=True)
    ex.feed([(9 * MS, "tactile/frame", _tactile(5.0, 9 * MS))])
    ex.feed([(11 * MS, "ft/wrench", w) for w in wrenches])
    ex.run()
    return ex.published["contact"], ex


@pytest.mark.parametrize("tactile", [True, False])
def test_one_contact_carries_every_sample_of_the_batch(tactile):
    loads = [(4.0 + 0.1 * k, 0.3 * k, 1e-3 * k) for k in range(5)]
    wrenches = [_wrench(k, *load) for k, load in enumerate(loads)]
    contacts, ex = _run(wrenches, tactile)
    assert len(contacts) == 1
    c = contacts[0]
    assert c.header.stamp_ns == wrenches[-1].header.stamp_ns and c.f_n == pytest.approx(loads[-1][0])
    assert c.earlier_samples == 4 and c.status == "ok" and c.has_tactile is tactile
    assert c.earlier_stamp_ns.tolist() == [w.header.stamp_ns for w in wrenches[:-1]]
    assert c.header.sources["ft_oldest"] == wrenches[0].header.stamp_ns
    assert c.earlier_f_n == pytest.approx([f_n for f_n, _, _ in loads[:-1]])
    assert c.earlier_f_tx == pytest.approx([f_x for _, f_x, _ in loads[:-1]])
    assert c.earlier_f_ty == pytest.approx([-0.5 * f_x for _, f_x, _ in loads[:-1]])
    assert c.earlier_tau == pytest.approx([tau for _, _, tau in loads[:-1]])
    assert (c.earlier_status == SAMPLE_OK).all()
    assert ex.host("fusion").counters["fusion.samples"] == 5
    assert decode(encode(c), Contact).earlier_f_n == pytest.approx(c.earlier_f_n)  # within the declared bounds


def test_a_batch_of_one_carries_no_earlier_samples():
    (c,), _ = _run([_wrench(0, 4.0, 0.2, 0.0)])
    assert c.earlier_samples == 0 and c.earlier_f_n.size == 0 and c.status == "ok"
    assert "ft_oldest" not in c.header.sources


@pytest.mark.parametrize("bad", ["stale", "disconnected", "device-status 0x0002"])
def test_an_unusable_earlier_sample_carries_its_status_onto_the_contact(bad):
    wrenches = [_wrench(0, 4.0, 0.1, 0.0), _wrench(1, 4.0, 0.1, 0.0, status=bad), _wrench(2, 4.0, 0.1, 0.0),
                _wrench(3, 4.0, 0.1, 0.0, status="stale"), _wrench(4, 4.0, 0.1, 0.0)]
    (c,), _ = _run(wrenches)
    assert c.earlier_status.tolist() == [SAMPLE_OK, SAMPLE_UNUSABLE, SAMPLE_OK, SAMPLE_UNUSABLE]
    assert c.status == bad  # the first unusable one's: the grip controller holds on it


def test_a_zeroed_earlier_sample_beside_a_pressed_pad_is_implausible():
    """A biased F/T reading inside a batch is caught as it would be alone."""
    (c,), ex = _run([_wrench(0, 0.0, 0.0, 0.0), _wrench(1, 5.0, 0.1, 0.0)])
    assert c.earlier_status.tolist() == [SAMPLE_UNUSABLE] and c.status == "implausible"
    assert ex.host("fusion").counters["fusion.implausible_ft"] == 1


def test_an_earlier_sample_without_load_is_usable_data_and_no_fault():
    """Lifting off inside a batch is no fault: the sample is usable, the contact's status stays the newest's."""
    (c,), _ = _run([_wrench(0, 4.0, 0.1, 0.0), _wrench(1, 5.0, 0.1, 0.0)], tactile=False)
    (lifted,), _ = _run([_wrench(0, 0.01, 0.0, 0.0), _wrench(1, 5.0, 0.1, 0.0)], tactile=False)
    assert lifted.earlier_status.tolist() == [SAMPLE_NO_CONTACT] and lifted.status == c.status == "ok"


def test_the_newest_samples_own_fault_wins():
    (c,), _ = _run([_wrench(0, 4.0, 0.1, 0.0, status="stale"), _wrench(1, 4.0, 0.1, 0.0, status="disconnected")])
    assert c.status == "disconnected"


def test_a_backlog_beyond_one_contact_makes_several_every_sample_carried():
    """After a stall: consecutive contacts of at most SAMPLES_PER_CONTACT samples, oldest first."""
    assert SAMPLES_PER_CONTACT == MAX_EARLIER_SAMPLES + 1
    wrenches = [_wrench(k, 4.0, 0.1, 0.0) for k in range(2 * SAMPLES_PER_CONTACT + 5)]
    contacts, ex = _run(wrenches, tactile=False)  # F/T only: the backlog outlasts the pairing window
    assert [c.earlier_samples + 1 for c in contacts] == [SAMPLES_PER_CONTACT, SAMPLES_PER_CONTACT, 5]
    carried = [s for c in contacts for s in (*c.earlier_stamp_ns.tolist(), c.header.stamp_ns)]
    assert carried == [w.header.stamp_ns for w in wrenches]
    c = ex.host("fusion").counters
    assert c["in.ft/wrench.dropped"] == 0 and c["fusion.samples"] == len(wrenches)


def test_an_earlier_sample_outside_the_pairing_window_is_not_paired_with_the_frame():
    """A backlog at 1 kHz spans 64 ms: its samples farther than max_pair_age_ms from the
    tactile frame are carried by an F/T-only contact, as each would be alone, never
    judged with a pressure frame they were not paired with."""
    frame_ns = 100 * MS
    wrenches = [Wrench(force=np.array([0.1, 0.0, -4.0]), torque=np.zeros(3), frame="pad", device_seq=k,
                       header=Header(40 * MS + k * MS, k, 40 * MS + k * MS, {})) for k in range(64)]  # 40 … 103 ms
    ex = InProcessExecutor([Fusion(FusionParams(max_pair_age_ms=10.0))], keep_published=True)
    ex.feed([(frame_ns, "tactile/frame", _tactile(4.0, frame_ns))])
    ex.feed([(104 * MS, "ft/wrench", w) for w in wrenches])
    ex.run()
    contacts = ex.published["contact"]
    carried = [s for c in contacts for s in (*c.earlier_stamp_ns.tolist(), c.header.stamp_ns)]
    assert carried == [w.header.stamp_ns for w in wrenches]  # every sample, once, oldest first
    for c in contacts:
        stamps = np.array([*c.earlier_stamp_ns.tolist(), c.header.stamp_ns])
        if c.has_tactile:
            assert (np.abs(stamps - frame_ns) <= 10 * MS).all(), stamps.tolist()
        else:
            assert c.tactile_status == "unpaired"
    assert sum(c.has_tactile for c in contacts) >= 1 and sum(not c.has_tactile for c in contacts) >= 1
