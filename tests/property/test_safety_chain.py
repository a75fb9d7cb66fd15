"""The safety contract (docs/safety.md) through the whole control chain, under hypothesis.

Random input histories — each step a sensor sample that is fine, dropped, late,
stamped in the past or the future, marked stale or disconnected, zeroed (a biased
F/T sensor) or carrying a random load — go through the real fusion, slip detector
and grip controller nodes on the in-process executor. Whatever happens:

More in docs/modules.md, `tests/property/test_safety_chain.py`.
"""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from slipstack.messages import Header, TactileFrame, Wrench
from slipstack.nodes.fusion import Fusion, FusionParams
from slipstack.nodes.grip_controller import GripController, GripControllerParams
from slipstack.nodes.runtime.inprocess import InProcessExecutor
from slipstack.nodes.slip_detector import SlipDetector, SlipDetectorParams

MS = 1_000_000
F_NOM, F_MAX, RATE = 2.0, 20.0, 200.0
PITCH_M = 1.25e-3
N = 256

FAULTS = ["ok", "ok", "ok", "drop", "late", "old_stamp", "future_stamp", "stale", "disconnected", "zero"]


def _pressure(f_n: float, centre: int) -> np.ndarray:
    p = np.zeros((16, 16), dtype=np.float32)
    r0 = min(max(centre, 0), 10)
    p[r0:r0 + 6, 5:11] = f_n / (36 * PITCH_M**2)
    return p.reshape(-1)


step = st.tuples(
    st.sampled_from(FAULTS),  # what happens to the F/T sample
    st.sampled_from(FAULTS),  # what happens to the tactile frame
    st.floats(0.5, 12.0),  # f_n pressing, N
    st.floats(-1.2, 1.2),  # tangential load over mu f_n
    st.floats(-3e-3, 3e-3),  # torque, N·m
    st.integers(0, 10),  # where the contact patch sits
)


def _events(history: list[tuple]) -> tuple[list, dict[int, str], dict[int, str]]:
    """The frames to feed, and the fault of each F/T and tactile sample by its stamp."""
    events, ft_fault, tac_fault_by_stamp = [], {}, {}
    for k, (ft_step, tactile_step, f_n, load, tau, centre) in enumerate(history):
        t = (k + 1) * MS
        for fault, topic in ((tactile_step, "tactile/frame"), (ft_step, "ft/wrench")):
            if fault == "drop":
                continue
            arrive = t + (30 * MS if fault == "late" else 0) + (1 if topic == "ft/wrench" else 0)
            # odd offsets keep every stamp unique, so a stamp names its sample
            stamp = t - 40 * MS - 7 if fault == "old_stamp" else t + 500 * MS + 3 if fault == "future_stamp" else t
            status = fault if fault in ("stale", "disconnected") else "ok"
            header = Header(stamp, k, stamp, {})
            if topic == "ft/wrench":
                f = 0.0 if fault == "zero" else f_n
                msg = Wrench(force=np.array([load * 0.45 * f, 0.0, -f]), torque=np.array([0.0, 0.0, tau]),
                             frame="pad", status=status, header=header)
                ft_fault[stamp] = fault
            else:
                msg = TactileFrame(rows=16, cols=16, pitch_m=PITCH_M, pressure_pa=_pressure(f_n, centre),
                                   saturated=np.zeros(N, bool), dead=np.zeros(N, bool), status=status,
                                   header=header)
                tac_fault_by_stamp[stamp] = fault
            events.append((arrive, topic, msg))
    return events, ft_fault, tac_fault_by_stamp


@settings(max_examples=60, deadline=None)
@given(history=st.lists(step, min_size=5, max_size=120), law=st.sampled_from(["exact", "linear", "tactile14"]))
def test_no_input_history_lowers_the_grip_on_bad_data_or_breaks_the_bounds(history, law):
    nodes = [
        Fusion(FusionParams()),
        SlipDetector(SlipDetectorParams(method="exact", mu=0.45, also=[])),
        GripController(GripControllerParams(law=law, mu=0.45, beta_m=2.5e-3, f_nom_n=F_NOM, f_max_n=F_MAX,
                                            max_rate_n_per_s=RATE)),
    ]
    if law == "tactile14":
        from slipstack.nodes.cor_estimator import CorEstimator, CorParams
        nodes.insert(2, CorEstimator(CorParams(mu=0.45)))
    ex = InProcessExecutor(nodes)
    events, ft_fault, tac_fault = _events(history)
    ex.feed(events)
    ex.run(until_ns=(len(history) + 100) * MS)

    assert all(h.counters.get("handler_errors", 0) == 0 for h in ex.hosts), ex.logs[-3:]
    cmds = ex.published["grip/command"]
    prev, prev_t = None, None
    for c in cmds:
        f, t = c.f_n_desired, c.header.pub_ns
        assert math.isfinite(f) and F_NOM - 1e-9 <= f <= F_MAX + 1e-9
        if prev is not None:
            assert abs(f - prev) <= RATE * (t - prev_t) * 1e-9 + 1e-9
            if c.reason == "fail-safe":
                assert f >= prev - 1e-12, f"fail-safe lowered the grip {prev} -> {f}"
        ft = c.header.sources.get("ft")
        if ft is not None and ft_fault[ft] in ("stale", "disconnected"):
            assert c.reason == "fail-safe", f"a {ft_fault[ft]} F/T sample drove a {c.reason} command"
        if prev is not None and f < prev - 1e-12:
            assert ft is not None and ft_fault[ft] == "ok", f"lowered on a {ft_fault.get(ft)} F/T sample"
            if law != "linear":
                tac = c.header.sources.get("tactile")
                assert tac is not None, "lowered without a tactile frame"
                assert tac_fault[tac] in ("ok", "zero"), f"lowered on a {tac_fault[tac]} tactile frame"
        prev, prev_t = f, t
