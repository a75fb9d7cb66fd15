"""An F/T sensor faster than the rig's internal step (the ATI Net F/T's 7 kHz against
a 1 ms step) is sampled at its own rate: every sample time gets a sample, numbered in
order, stamped at or before the step that takes it; slower sensors are unchanged."""

from __future__ import annotations

from slipstack.lib.rig.sensors import FtSample, TactileSample
from slipstack.lib.rig.simulator import Simulator
from slipstack.nodes.rig import load_scene_by_name, with_rates


def _samples(ft_hz: float, seconds: float = 0.2):
    sim = Simulator(with_rates(load_scene_by_name("default"), ft_hz=ft_hz, tactile_hz=500.0))
    out = sim.step_until(round(seconds * 1e9))
    return [s for s in out if isinstance(s, FtSample)], [s for s in out if isinstance(s, TactileSample)]


def test_seven_kilohertz_against_a_one_millisecond_step():
    ft, tactile = _samples(7000.0)
    assert len(ft) == 7 * 200 + 1  # t = 0 … 200 ms at 1/7 ms
    assert [s.device_seq for s in ft] == list(range(len(ft)))
    times = [s.stamp_ns for s in ft]
    assert all(b > a for a, b in zip(times, times[1:]))
    assert len(tactile) == 101


def test_one_kilohertz_is_one_sample_per_step():
    ft, _ = _samples(1000.0)
    assert len(ft) == 201 and [s.stamp_ns for s in ft] == [k * 1_000_000 for k in range(201)]
