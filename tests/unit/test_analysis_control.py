"""The control figures' text (analysis/figures_control.py) on a real lock-step run: a run whose
set point sits at its ceiling says how often; set points pair with the load they answered."""

from __future__ import annotations

import re

import numpy as np
import pytest

pytest.importorskip("matplotlib")  # analysis/figures.py draws with it

from slipstack.analysis.figures_control import _friction_note, saturation_note, set_points  # noqa: E402
from slipstack.analysis.runs import Experiment, run_experiment  # noqa: E402


@pytest.fixture(scope="module")
def saturated():
    """fig10's linear law with f_max lowered to 3 N, 2 s: the load asks for more from about 1.2 s."""
    return run_experiment(Experiment("fig10", "fig10", "linear law against a 3 N ceiling", {"f_max_n": 3.0}),
                          duration_s=2.0)


def test_a_saturated_run_prints_the_share_of_commands_at_the_ceiling(saturated):
    commands = saturated["grip/command"]["f_n"]
    share = np.mean(commands >= 3.0 - 1e-9) * 100
    assert 10.0 < share < 60.0  # the run did saturate, and not from its start
    for text in (saturation_note(saturated), _friction_note(saturated)):
        printed = re.search(r"ceiling f_max = 3 N in ([\d.]+) % of the commands", text)
        assert printed and float(printed.group(1)) == pytest.approx(share, abs=0.05), text


def test_an_unsaturated_run_says_nothing_of_a_ceiling():
    run = run_experiment(Experiment("fig10", "fig10", "linear law, default ceiling"), duration_s=1.0)
    assert saturation_note(run) == "" and "ceiling" not in _friction_note(run)


def test_each_set_point_answers_the_verdict_at_or_before_it(saturated):
    sp = set_points(saturated)
    s = saturated["slip"]
    assert len(sp.t) == len(saturated["grip/command"]["t"])
    k = np.searchsorted(s["t"], sp.t, side="right") - 1
    assert (k >= 0).all() and (s["t"][k] <= sp.t).all()
    np.testing.assert_allclose(sp.f_t, np.hypot(*s["f_t"][k].astype(float).T))
