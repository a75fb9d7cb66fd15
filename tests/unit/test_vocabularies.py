"""The vocabularies are enums whose values are the wire spellings recordings carry."""

from __future__ import annotations

import dataclasses

import numpy as np

from slipstack.lib.status import SLIP_STATES, CorSolver, SlipCase, SlipState, SolverStatus
from slipstack.messages import Cor, Slip, decode, encode
from slipstack.nodes.cor_estimator import SOLVERS, CorEstimator, CorParams


def _choices(cls, name):
    return next(f for f in dataclasses.fields(cls) if f.name == name).metadata["bounds"].choices


def test_wire_spellings_are_the_recorded_ones():
    assert [s.value for s in SlipState] == ["stick", "translation", "rotation", "combined", "no-contact"]
    assert [c.value for c in SlipCase] == ["rotation", "translation", "on-taxel", "none"]
    assert (SolverStatus.NO_CONTACT.value, SolverStatus.ON_TAXEL.value) == ("no_contact", "on_taxel")
    assert set(_choices(Slip, "state")) == {s.value for s in SlipState}
    assert set(_choices(Cor, "case")) == {c.value for c in SlipCase}
    assert SLIP_STATES == {"translation", "rotation", "combined"}


def test_an_enum_member_encodes_to_the_same_bytes_as_its_spelling():
    by_member = encode(Slip(state=SlipState.ROTATION, f_t=np.zeros(2), p_c=np.zeros(2)))
    by_string = encode(Slip(state="rotation", f_t=np.zeros(2), p_c=np.zeros(2)))
    assert by_member == by_string and decode(by_member, Slip).state == SlipState.ROTATION


def test_cor_estimator_takes_the_one_set_of_solver_names():
    assert SOLVERS == ("exact", "robust", "paper") == tuple(CorSolver)
    for solver in CorSolver:
        assert CorEstimator(CorParams(solver=solver.value)).params.solver == solver
