"""Safety with batched F/T samples (docs/safety.md): through the real fusion, slip
detector and grip controller on the in-process executor, F/T samples arrive several at
one instant (one wake-up's batch, as at 7 kHz), some of them stale, disconnected or
zeroed (a biased sensor beside a pressed pad). A command derived from a batch that held
an unusable sample is ``fail-safe`` and never lower than the one before, whichever
sample of the batch it was; only a batch of good samples may lower the grip."""

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
PERIOD_NS = 143_000  # 7 kHz
F_NOM, F_MAX, RATE, MU = 2.0, 20.0, 200.0, 0.45
PITCH_M = 1.25e-3
BAD = ("stale", "disconnected", "zero")

sample = st.tuples(st.sampled_from(("ok",) * 6 + BAD), st.floats(1.0, 10.0), st.floats(-1.2, 1.2))
wake_ups = st.lists(st.lists(sample, min_size=1, max_size=8), min_size=3, max_size=40)


def _tactile(f_n: float, stamp: int) -> TactileFrame:
    p = np.zeros((16, 16), dtype=np.float32)
    p[5:11, 5:11] = f_n / (36 * PITCH_M**2)
    return TactileFrame(rows=16, cols=16, pitch_m=PITCH_M, pressure_pa=p.reshape(-1), saturated=np.zeros(256, bool),
                        dead=np.zeros(256, bool), header=Header(stamp, stamp, stamp, {}))


@st.composite
def backlog(draw) -> list[tuple[str, float, float]]:
    """One wake-up after a stall: 65–197 samples (up to four contacts), their loads from a
    drawn seed and at most three bad samples at drawn places, so some contacts of a backlog
    hold none. (Drawing every sample's fault and floats, as ``wake_ups`` does, asked
    hypothesis for more data than it allows per example: its ``data_too_large`` check failed.)"""
    n = draw(st.integers(65, 3 * 64 + 5))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    f_n, load = rng.uniform(1.0, 10.0, n), rng.uniform(-1.2, 1.2, n)
    faults = ["ok"] * n
    for i, fault in draw(st.lists(st.tuples(st.integers(0, n - 1), st.sampled_from(BAD)), max_size=3)):
        faults[i] = fault
    return [(faults[i], float(f_n[i]), float(load[i])) for i in range(n)]


backlogs = st.lists(backlog(), min_size=2, max_size=5)
"""Wake-ups after stalls, each handed to the slip detector as up to four contacts at one instant."""


@settings(max_examples=40, deadline=None)
@given(wake_ups=wake_ups, law=st.sampled_from(["exact", "linear"]))
def test_an_unusable_sample_in_a_batch_never_lets_the_grip_drop(wake_ups, law):
    _check_the_grip_never_drops_on_a_bad_batch(wake_ups, law)


@settings(max_examples=25, deadline=None)
@given(wake_ups=backlogs, law=st.sampled_from(["exact", "linear"]))
def test_an_unusable_sample_anywhere_in_a_backlog_never_lets_the_grip_drop(wake_ups, law):
    _check_the_grip_never_drops_on_a_bad_batch(wake_ups, law)


def _check_the_grip_never_drops_on_a_bad_batch(wake_ups: list, law: str) -> None:
    ex = InProcessExecutor([
        Fusion(FusionParams()),
        SlipDetector(SlipDetectorParams(method="exact", mu=MU, also=[])),
        GripController(GripControllerParams(law=law, mu=MU, beta_m=2.5e-3, f_nom_n=F_NOM, f_max_n=F_MAX,
                                            max_rate_n_per_s=RATE)),
    ])
    events, bad_batch = [], {}
    t, seq = MS, 0
    for batch in wake_ups:
        arrive = t + len(batch) * PERIOD_NS
        events.append((arrive - PERIOD_NS // 2, "tactile/frame", _tactile(batch[-1][1], arrive - PERIOD_NS // 2)))
        for fault, f_n, load in batch:
            t += PERIOD_NS
            seq += 1
            f = 0.0 if fault == "zero" else f_n
            status = fault if fault in ("stale", "disconnected") else "ok"
            events.append((arrive, "ft/wrench", Wrench(
                force=np.array([load * MU * f, 0.0, -f]), torque=np.zeros(3), frame="pad", status=status,
                header=Header(t, seq, t, {}))))
        bad_batch[t] = any(fault in BAD for fault, _, _ in batch)  # by the newest sample's stamp
    ex.feed(events)
    ex.run(until_ns=t + 100 * MS)

    assert all(h.counters.get("handler_errors", 0) == 0 for h in ex.hosts), ex.logs[-3:]
    fusion = ex.host("fusion").counters
    assert fusion["fusion.samples"] == fusion["in.ft/wrench.received"] == seq  # every sample reached a contact
    prev = None
    for c in ex.published["grip/command"]:
        f = c.f_n_desired
        assert math.isfinite(f) and F_NOM - 1e-9 <= f <= F_MAX + 1e-9
        newest = c.header.sources.get("ft")
        if newest in bad_batch and bad_batch[newest]:
            assert c.reason == "fail-safe", f"a batch with an unusable sample drove a {c.reason} command"
            assert prev is None or f >= prev - 1e-12, f"a batch with an unusable sample lowered the grip {prev} -> {f}"
        if prev is not None and f < prev - 1e-12:
            assert newest in bad_batch and not bad_batch[newest], "lowered without a batch of good samples"
        prev = f


def test_a_stale_sample_early_in_a_backlog_holds_the_grip():
    """A backlog after a stall makes several contacts at one instant; the slip detector
    takes them as one batch and publishes one verdict for the newest: a stale sample in
    the first contact must still make that verdict (and the command) hold the grip."""
    ex = InProcessExecutor([
        Fusion(FusionParams(use_tactile=False)),
        SlipDetector(SlipDetectorParams(method="coulomb", mu=MU, beta_m=2.5e-3, also=[])),
        GripController(GripControllerParams(law="linear", mu=MU, beta_m=2.5e-3, f_nom_n=F_NOM, f_max_n=F_MAX,
                                            max_rate_n_per_s=RATE)),
    ], keep_published=True)
    t, seq, events = MS, 0, []
    for k in range(40):  # 40 ms of one sample per wake-up under a heavy load: the grip rises
        t += MS
        seq += 1
        events.append((t, "ft/wrench", Wrench(force=np.array([0.9 * MU * 8.0, 0.0, -8.0]), torque=np.zeros(3),
                                              frame="pad", header=Header(t, seq, t, {}))))
    last_steady_ns, arrive = t, t + 200 * PERIOD_NS + MS
    for k in range(200):  # then a stall: 200 samples at one instant, the load gone, the 3rd one stale
        t += PERIOD_NS
        seq += 1
        events.append((arrive, "ft/wrench", Wrench(force=np.array([0.0, 0.0, -8.0]), torque=np.zeros(3), frame="pad",
                                                   status="stale" if k == 2 else "ok", header=Header(t, seq, t, {}))))
    ex.feed(events)
    ex.run(until_ns=arrive + 10 * MS)
    assert all(h.counters.get("handler_errors", 0) == 0 for h in ex.hosts), ex.logs[-3:]
    assert len(ex.published["contact"]) == 40 + 4  # the backlog made four contacts at one instant
    before = [c for c in ex.published["grip/command"] if c.header.stamp_ns <= last_steady_ns]
    after = [c for c in ex.published["grip/command"] if c.header.stamp_ns > last_steady_ns]
    assert after, "no command after the backlog"
    assert after[0].reason == "fail-safe" and after[0].f_n_desired >= before[-1].f_n_desired - 1e-12, (
        before[-1], after[0])
