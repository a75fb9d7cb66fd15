"""The simulated rig says when it fell behind real time: how late its tick came, how many
ticks that made up, and what to do, once at first and then at most every 10 s, on
``diagnostics`` (``last_error``) and in the log. The rig runs on a node host whose clock
the test drives, so a late tick is forced, not waited for."""

from __future__ import annotations

import pytest

from slipstack.lib.late_ticks import LateTicks
from slipstack.messages import decode
from slipstack.nodes.rig import Rig, RigParams
from slipstack.nodes.runtime.host import NodeHost

MS = 1_000_000


class DrivenRig:
    """The rig node (F/T on a simulated RDT device, no pad) on a host whose clock is ``self.now``."""

    def __init__(self) -> None:
        self.now = 0
        self.logs: list[str] = []
        self.rig = Rig(RigParams(rdt_host="sim:behind", rdt_port=1, tactile=False, wait_for_drivers_s=0.0))
        self.host = NodeHost(self.rig, lambda: self.now, lambda topic, payload: None, log=self.logs.append)
        self.host.call("start", self.rig.start, self.host)

    def ticks(self, count: int, *, late_ms: float = 0.0) -> None:
        """``count`` ticks, the first ``late_ms`` after its due time, the others on time."""
        self.now += round(late_ms * MS)
        for _ in range(count):
            self.now += MS
            self.host.fire_timer("tick")

    def behind_lines(self) -> list[str]:
        return [line for line in self.logs if "fell behind real time" in line]


def test_a_late_tick_is_told_in_numbers_with_what_to_do_on_diagnostics_and_in_the_log():
    r = DrivenRig()
    r.ticks(500)  # 0.5 s on time: nothing to say
    assert r.behind_lines() == [] and not decode(r.host.diagnostics()).last_error
    r.ticks(10, late_ms=113.0)
    [line] = r.behind_lines()
    assert line.startswith("error: fell behind real time: 1 tick late from 0.50 s into the scene, the worst by 113.0 ms")
    assert "113 ticks of 1 ms made up at once" in line and "up to 113 ms late" in line
    for advice in ("`realtime:=10`", "ulimit -r 10", "ft_rate_hz:=250 tactile_rate_hz:=125", "--lockstep"):
        assert advice in line, advice
    assert decode(r.host.diagnostics()).last_error == line.removeprefix("error: ")
    assert r.host.counters["rig.late_ticks"] == 1


def test_late_ticks_are_summed_up_at_most_every_ten_seconds():
    r = DrivenRig()
    r.ticks(100)
    r.ticks(100, late_ms=20.0)  # reported at once
    for _ in range(5):  # 5 more within the next 10 s: held back
        r.ticks(1000, late_ms=30.0)
    assert len(r.behind_lines()) == 1
    r.ticks(5000, late_ms=50.0)  # past 10 s since the report: the six late ticks since then, in one line
    lines = r.behind_lines()
    assert len(lines) == 2 and "6 ticks late from" in lines[1] and "the worst by 50.0 ms" in lines[1], lines
    assert "7 late ticks in all" in lines[1] and r.host.counters["rig.late_ticks"] == 7


def test_a_tick_within_the_tolerance_or_a_burst_of_made_up_ticks_is_not_late():
    pace = LateTicks(period_ns=MS, late_after_ns=5 * MS, report_every_ns=10_000 * MS)
    late = [pace.tick(t) for t in (MS, 2 * MS, 8 * MS, 9 * MS)]  # 5 ms late: within the tolerance
    assert late == [False] * 4 and pace.report(9 * MS, 0) is None
    late = [pace.tick(30 * MS) for _ in range(21)]  # 20 ms late, then the ticks made up at once
    assert late == [True] + [False] * 20 and pace.late_ticks == 1 and pace.worst_ns == 20 * MS
    assert "the worst by 20.0 ms (20 ticks of 1 ms made up at once" in pace.report(30 * MS, 0)
    assert pace.report(30 * MS, 0) is None  # told
    with pytest.raises(ValueError):
        LateTicks(period_ns=0, late_after_ns=0, report_every_ns=0)


def test_the_report_of_a_loop_under_sched_fifo_does_not_advise_realtime():
    """The rig runs under SCHED_FIFO by default where the launcher may set it: its report
    used to advise `realtime:=10` all the same."""
    for realtime, advised in ((False, True), (True, False)):
        pace = LateTicks(period_ns=MS, late_after_ns=5 * MS, report_every_ns=0)
        pace.tick(0)
        pace.tick(20 * MS)
        report = pace.report(20 * MS, 0, realtime)
        assert ("`realtime:=10`" in report) is advised, report
        assert "free a core" in report and "--lockstep" in report
