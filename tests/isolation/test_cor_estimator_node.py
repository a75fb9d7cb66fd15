"""The COR estimator node behind fusion on hand-made frames (in-process executor): each
solver publishes its library solver's answer for the fused contact, with the parameters
the node documents, and says on ``diagnostics`` when a solver could not compute."""

from __future__ import annotations

import numpy as np
import pytest

from sensor_frames import MS, PITCH_M, tactile, wrench

from slipstack.lib.contact_view import pad_positions
from slipstack.lib.cor import paper_cor, robust_cor
from slipstack.lib.errors import ConfigError
from slipstack.lib.limit_set import load_factor
from slipstack.messages import Contact, Cor
from slipstack.nodes.cor_estimator import CorEstimator, CorParams
from slipstack.nodes.fusion import Fusion
from slipstack.nodes.runtime.inprocess import InProcessExecutor

MU = 0.5


def lopsided_pressure() -> np.ndarray:
    """A 5×4 patch (Pa) pressed harder on its left: the COR of a twist is off its centre."""
    p = np.zeros((16, 16), np.float32)
    p[5:10, 4:8] = np.linspace(3.0, 1.0, 4) / (20 * 2 * PITCH_M**2)  # about 2 N in all
    return p.reshape(-1)


def run(params: CorParams, events) -> tuple[list[Contact], list[Cor], dict[str, float]]:
    ex = InProcessExecutor([Fusion(), CorEstimator(params)], diagnostics_period_s=0.001)
    ex.feed(events)
    ex.run(until_ns=max(t for t, _, _ in events) + 2 * MS)
    counters = [d for d in ex.published["diagnostics"] if d.node == "cor_estimator"][-1].counters
    return ex.published["contact"], ex.published["cor"], counters


def twisted(f_n: float = 2.0, f_t: float = 0.3, tau: float = 2e-3) -> list:
    return [tactile(0, 0.0, pressure_pa=lopsided_pressure()), wrench(1, f_n, f_t, tau=tau)]


def solve(solver: str, c: Contact, **kw):
    positions = pad_positions(c.rows, c.cols, c.pitch_m)
    if solver == "exact":
        return load_factor(c.phi, positions, c.f_t, c.tau, MU, c0=None)
    return (robust_cor if solver == "robust" else paper_cor)(c.phi, positions, c.f_t, c.tau, MU, c0=None, **kw)


@pytest.mark.parametrize(("params", "library_args"), [
    (CorParams(solver="exact", mu=MU), {}),
    (CorParams(solver="robust", mu=MU), {}),
    (CorParams(solver="paper", mu=MU), {"gain": 0.5}),  # the paper's gain h by default
    (CorParams(solver="paper", mu=MU, paper_gain=0.3), {"gain": 0.3}),
])
def test_each_solver_publishes_its_library_solvers_answer_for_the_contact(params, library_args):
    (contact,), (cor,), _ = run(params, twisted())
    ref = solve(params.solver, contact, **library_args)
    assert cor.case == ref.case.value == "rotation"
    assert tuple(cor.p_c) == ref.p_c
    assert (cor.load_torque, cor.torque_capacity, cor.iterations) == (ref.load_torque, ref.torque_capacity,
                                                                     ref.iterations)
    assert cor.status == ref.status.value and cor.converged


def test_the_solvers_differ_on_the_test_contact():
    # what makes the test above tell the solvers (and the paper's gains) apart
    (contact,), _, _ = run(CorParams(mu=MU), twisted())
    robust, paper, slow = solve("robust", contact), solve("paper", contact, gain=0.5), solve("paper", contact, gain=0.3)
    assert robust.iterations != paper.iterations != slow.iterations and robust.p_c != paper.p_c


def test_by_default_every_contact_is_solved_and_per_tactile_frame_only_the_first_of_a_frame():
    events = twisted() + [wrench(2, 2.0, 0.3, tau=2e-3), wrench(3, 2.0, 0.3, tau=2e-3)]
    _, cors, _ = run(CorParams(mu=MU), events)
    assert len(cors) == 3
    _, cors, counters = run(CorParams(mu=MU, per_tactile_frame=True), events)
    assert len(cors) == 1 and counters["cor.skipped_same_tactile_frame"] == 2


def test_a_translating_contact_has_no_cor_and_publishes_p_c_zero():
    (contact,), (cor,), _ = run(CorParams(solver="robust", mu=MU), twisted(f_t=1.5, tau=0.0))  # |f_t| > mu f_n
    assert cor.case == "translation" and cor.gamma == pytest.approx(1.5 / (MU * contact.f_n), rel=1e-12)
    assert list(cor.p_c) == [0.0, 0.0]


def test_a_cor_the_solver_could_not_compute_is_counted_by_its_status():
    # the paper's iteration on two equal taxels pulled along the line through them
    pair = np.zeros(256, np.float32)
    pair[5 * 16 + 5] = pair[5 * 16 + 7] = 100.0 / PITCH_M**2
    events = twisted() + [tactile(10, 0.0, pressure_pa=pair), wrench(11, 200.0, 5.0)]
    _, cors, counters = run(CorParams(solver="paper", mu=MU, warm_start=False), events)
    assert cors[0].status == "converged" and cors[1].status == "singular" and not cors[1].converged
    assert {k: v for k, v in counters.items() if k.startswith("cor.")} == {"cor.singular": 1}


@pytest.mark.parametrize("pool", [0, -2])
def test_a_pool_under_one_is_a_config_error(pool):
    """As the slip detector's (it was taken for 1, silently)."""
    with pytest.raises(ConfigError, match=r"cor_estimator pool must be an integer >= 1"):
        CorParams(pool=pool)


def test_a_pool_that_does_not_divide_the_pad_solves_it_unpooled_and_says_so():
    """``pool`` 3 on the 16×16 pad: the contact is solved at its full resolution and the
    node says once which pools fit (it raised on every contact: no ``cor`` at all)."""
    ex = InProcessExecutor([Fusion(), CorEstimator(CorParams(solver="exact", mu=MU, pool=3))],
                           diagnostics_period_s=0.001)
    ex.feed(twisted() + [wrench(2, 2.0, 0.3, tau=2e-3)])
    ex.run(until_ns=4 * MS)
    contacts, cors = ex.published["contact"], ex.published["cor"]
    last = [d for d in ex.published["diagnostics"] if d.node == "cor_estimator"][-1]
    assert last.counters.get("handler_errors", 0) == 0, last.last_error
    assert len(cors) == len(contacts) == 2
    # the unpooled COR (the second warm-started from the first: to 1 nm)
    assert np.allclose([c.p_c for c in cors], [solve("exact", c).p_c for c in contacts], rtol=0.0, atol=1e-9)
    assert "pool 3 does not divide the pad's 16x16" in last.last_error, last.last_error
    assert len([line for line in ex.logs if "pool 3 does not divide" in line]) == 1, ex.logs
