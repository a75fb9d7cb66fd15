"""The slip detector node on hand-made frames through fusion and the in-process executor:
what it says on ``diagnostics`` when its deciding test cannot compute (docs/safety.md)."""

from __future__ import annotations

import numpy as np

from sensor_frames import MS, PITCH_M, tactile, wrench

from slipstack.nodes.fusion import Fusion
from slipstack.nodes.runtime.inprocess import InProcessExecutor
from slipstack.nodes.slip_detector import SlipDetector, SlipDetectorParams


def test_a_verdict_the_solver_could_not_compute_is_counted_by_its_status_and_not_ok():
    # The paper's fixed-gain COR iteration on two equal taxels two columns apart, pulled along
    # the line through them, fails (singular from a cold start, diverged when warm-started from
    # the contact before). The well-posed contact before it is not counted.
    detector = SlipDetector(SlipDetectorParams(method="tactile_cor", mu=0.5, also=[]))
    ex = InProcessExecutor([Fusion(), detector], diagnostics_period_s=0.001)
    pair = np.zeros(256, np.float32)
    pair[5 * 16 + 5] = pair[5 * 16 + 7] = 100.0 / PITCH_M**2  # 100 N each
    ex.feed([tactile(0, 4.0), wrench(1, 4.0, 0.2), wrench(2, 4.0, 0.2),
             tactile(10, 0.0, pressure_pa=pair), wrench(11, 200.0, 5.0), wrench(12, 200.0, 50.0)])
    ex.run(until_ns=15 * MS)
    well_posed, failed = ex.published["slip"][:2], ex.published["slip"][2:]
    assert [s.status for s in well_posed] == ["ok", "ok"]
    assert len(failed) == 2 and failed[0].status in ("singular", "diverged", "max_iter")
    assert failed[1].status == failed[0].status  # never "ok": the controller holds
    counters = [d for d in ex.published["diagnostics"] if d.node == "slip_detector"][-1].counters
    assert {k: v for k, v in counters.items() if k.startswith("slip.")} == {f"slip.{failed[0].status}": 2}


def test_a_tactile_test_on_a_stack_without_tactile_says_which_test_to_use():
    """``slipstack launch tactile:=false`` keeps the default ``method = exact``: every verdict
    is ``tactile_off`` and the grip holds (safe), and the detector says once, on
    ``diagnostics`` and in the log, that the test needs the pad and which F/T test to pick."""
    from slipstack.nodes.fusion import FusionParams

    detector = SlipDetector(SlipDetectorParams(method="exact", mu=0.5))
    ex = InProcessExecutor([Fusion(FusionParams(use_tactile=False)), detector], diagnostics_period_s=0.001)
    ex.feed([wrench(k, 4.0, 0.2) for k in range(1, 6)])
    ex.run(until_ns=10 * MS)
    assert {s.status for s in ex.published["slip"]} == {"tactile_off"}
    last = [d for d in ex.published["diagnostics"] if d.node == "slip_detector"][-1]
    assert "needs the tactile pad" in last.last_error and "method:=coulomb" in last.last_error, last.last_error
    said = [line for line in ex.logs if "needs the tactile pad" in line]
    assert len(said) == 1, said  # once, not per contact
