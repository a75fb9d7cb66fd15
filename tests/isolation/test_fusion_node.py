"""The fusion node with its default parameters, on hand-made frames through the in-process
executor: which tactile frame pairs with a wrench, what an F/T-only contact says, the
plausibility check, and what the node counts on ``diagnostics`` (docs/safety.md)."""

from __future__ import annotations

import numpy as np
import pytest

from sensor_frames import MS, pressure_for, tactile, wrench

from slipstack.messages import Contact, Diagnostics
from slipstack.nodes.fusion import Fusion, FusionParams
from slipstack.nodes.runtime.inprocess import InProcessExecutor

DEFAULTS = FusionParams()


def fuse_events(events, params: FusionParams = DEFAULTS) -> tuple[list[Contact], dict[str, float]]:
    """The contacts a fresh fusion node publishes for ``events``, and its last counters."""
    ex = InProcessExecutor([Fusion(params)], diagnostics_period_s=0.001)
    ex.feed(events)
    ex.run(until_ns=max(t for t, _, _ in events) + 2 * MS)  # one diagnostics report after the last frame
    diags: list[Diagnostics] = ex.published["diagnostics"]
    return ex.published["contact"], diags[-1].counters


@pytest.mark.parametrize(("tactile_stamp_ns", "wrench_stamp_ns", "paired"), [
    (0, 10 * MS, True),                 # exactly max_pair_age_ms (10 ms) older: still paired
    (0, 10 * MS + 5, False),            # 5 ns more: unpaired
    (15 * MS, 0, False),                # a tactile frame 15 ms *newer* than the wrench
    (10 * MS, 0, True),                 # ... and one exactly 10 ms newer
])
def test_a_tactile_frame_pairs_within_max_pair_age_either_side_of_the_wrench(tactile_stamp_ns, wrench_stamp_ns, paired):
    assert DEFAULTS.max_pair_age_ms == 10.0
    (contact,), _ = fuse_events([tactile(0, 4.0, stamp_ns=tactile_stamp_ns),
                                 wrench(0.5, 4.0, 0.2, stamp_ns=wrench_stamp_ns)])
    assert contact.has_tactile is paired
    if paired:
        assert contact.pair_offset_ns == tactile_stamp_ns - wrench_stamp_ns
        assert contact.header.sources == {"ft": wrench_stamp_ns, "tactile": tactile_stamp_ns}
        assert contact.phi.sum() == pytest.approx(4.0, rel=1e-9)
    else:
        assert contact.tactile_status == "unpaired" and contact.phi.size == 0
        assert contact.header.sources == {"ft": wrench_stamp_ns}


@pytest.mark.parametrize(("f_n", "status"), [(0.05, "no_contact"), (0.06, "ok"), (-0.2, "no_contact")])
def test_an_ft_only_contact_needs_more_than_min_normal_force(f_n, status):
    # no tactile frame yet: the wrench alone; contact above min_normal_force_n = 0.05 N
    (contact,), _ = fuse_events([wrench(1, f_n, 0.01)])
    assert contact.status == status and contact.tactile_status == "none" and not contact.has_tactile
    assert contact.f_n == pytest.approx(max(f_n, 0.0), abs=1e-15)  # the light touch as measured, a pull as 0
    assert contact.f_t == pytest.approx([0.01, 0.0])


@pytest.mark.parametrize("with_tactile", [False, True])
@pytest.mark.parametrize("ft_status", ["stale", "disconnected"])
def test_the_ft_sensors_own_status_reaches_the_contact(ft_status, with_tactile):
    # a stale F/T sample is never an 'ok' contact, paired with a fresh tactile frame or not
    events = [tactile(0, 4.0)] if with_tactile else []
    (contact,), _ = fuse_events(events + [wrench(1, 4.0, 0.2, status=ft_status)])
    assert contact.has_tactile is with_tactile
    assert contact.status == ft_status


@pytest.mark.parametrize(("pad_n", "ft_n", "implausible"), [
    (3.5, 1.0, True),    # pad 3.5 x the F/T force: over ft_plausibility_ratio (3)
    (2.5, 1.0, False),   # 2.5 x: within the tactile calibration's allowance
    (1.0, 0.2, True),    # 5 x with the pad at 1 N: over ft_plausibility_min_n (0.5 N)
    (0.45, 0.1, False),  # 4.5 x, but the pad's own force is below 0.5 N: not judged
])
def test_a_pad_pressed_far_harder_than_the_ft_sensor_says_is_implausible(pad_n, ft_n, implausible):
    contacts, counters = fuse_events([tactile(0, pad_n), wrench(1, ft_n, 0.0)])
    assert contacts[0].has_tactile
    assert (contacts[0].status == "implausible") is implausible
    assert counters.get("fusion.implausible_ft", 0) == int(implausible)


def test_a_plausibility_ratio_of_0_turns_the_check_off():
    # docs/safety.md: ft_plausibility_ratio:=0 for an uncalibrated pad
    contacts, counters = fuse_events([tactile(0, 4.0), wrench(1, 0.2, 0.0)], FusionParams(ft_plausibility_ratio=0.0))
    assert contacts[0].has_tactile and contacts[0].status == "ok"
    assert "fusion.implausible_ft" not in counters


def test_a_taxel_is_in_contact_just_above_the_noise_floor():
    assert DEFAULTS.noise_floor_pa == 2000.0
    pressure = pressure_for(4.0)
    pressure[0], pressure[1] = 2000.5, 1999.5  # a corner taxel just above, its neighbour just below
    (contact,), _ = fuse_events([tactile(0, 0.0, pressure_pa=pressure), wrench(1, 4.0, 0.0)])
    assert contact.has_tactile
    assert contact.mask[0] and not contact.mask[1]
    assert int(contact.mask.sum()) == 36 + 1
    assert contact.phi[0] == pytest.approx(4.0 * 2000.5 / float(pressure[5 * 16 + 5] * 36 + 2000.5), rel=1e-6)


def test_wrenches_in_the_sensor_frame_are_counted():
    _, counters = fuse_events([wrench(1, 4.0, 0.0, frame="sensor"), wrench(2, 4.0, 0.0, frame="sensor"),
                               wrench(3, 4.0, 0.0)])
    assert counters["fusion.sensor_frame_wrenches"] == 2


def test_negative_taxels_are_clipped_and_counted_once_per_frame():
    pressure = pressure_for(4.0)
    pressure[[0, 1, 2]] = -500.0  # an offset drifted below zero; no non-finite taxel beside them
    contacts, counters = fuse_events([tactile(0, 0.0, pressure_pa=pressure), wrench(1, 4.0, 0.0),
                                      wrench(2, 4.0, 0.0)])
    assert all(c.has_tactile and c.status == "ok" for c in contacts)  # clipped to 0, then fused
    assert not contacts[0].mask[[0, 1, 2]].any()
    assert float(contacts[0].phi.sum()) == pytest.approx(4.0, rel=1e-9)
    assert counters["fusion.negative_taxels"] == 3  # once for the frame, not per wrench
    assert counters.get("fusion.nonfinite_taxels", 0) == 0


def test_a_tactile_frame_with_a_non_finite_taxel_is_rejected_and_the_wrenches_still_fuse():
    pressure = pressure_for(4.0)
    pressure[7] = np.nan
    contacts, counters = fuse_events([tactile(0, 0.0, pressure_pa=pressure), wrench(1, 4.0, 0.0)])
    assert counters["in.tactile/frame.rejected"] == 1
    (contact,) = contacts
    assert contact.status == "ok" and not contact.has_tactile and contact.tactile_status == "none"
