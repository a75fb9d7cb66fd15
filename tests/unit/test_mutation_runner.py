"""The mutation runner of tests/mutation/: which mutants it plants and that it plants exactly them."""

from __future__ import annotations

import ast
import importlib.util
import sys
from pathlib import Path

import pytest

_PATH = Path(__file__).resolve().parents[1] / "mutation" / "mutate.py"
_spec = importlib.util.spec_from_file_location("slipstack_mutate", _PATH)
mutate = importlib.util.module_from_spec(_spec)
sys.modules[_spec.name] = mutate  # dataclasses look their module up by name
_spec.loader.exec_module(mutate)

SOURCE = '''"""Docstring: 1 < 2 is not mutated."""
from numba import njit

__all__ = ["f"]
LIMIT = 0.5


def f(x, y=3):
    """Nor is this 1 + 1."""
    if x != x:  # NaN guard
        return None
    if not x <= LIMIT and y > 0:
        return abs(-x) + max(x, y)
    raise ValueError(f"bad {x + 1}")


@njit
def kernel(a):
    total = 0.0
    for v in a:
        total += v * 2.0
    return total
'''


def _mutants():
    return mutate.collect_mutants("m.py", SOURCE)


def test_every_operator_is_planted_where_expected_and_nowhere_else():
    found = {(m.line, m.operator, m.original, m.mutated) for m in _mutants()}
    expected = {
        (5, "const", "0.5", "(1.5)"),
        (8, "const", "3", "(4)"),
        (10, "cmp", "x != x", "(x == x)"),
        (10, "guard", "x != x", "(False)"),
        (12, "guard", "not x <= LIMIT and y > 0", "(False)"),
        (12, "bool", "not x <= LIMIT and y > 0", "(not x <= LIMIT or y > 0)"),
        (12, "not", "not x <= LIMIT", "(x <= LIMIT)"),
        (12, "cmp", "x <= LIMIT", "(x < LIMIT)"),
        (12, "cmp", "y > 0", "(y >= 0)"),
        (12, "const", "0", "(1)"),
        (13, "return", "return abs(-x) + max(x, y)", "return None"),
        (13, "binop", "abs(-x) + max(x, y)", "(abs(-x) - max(x, y))"),
        (13, "abs", "abs(-x)", "(-x)"),
        (13, "neg", "-x", "(x)"),
        (13, "minmax", "max(x, y)", "(min(x, y))"),
        (19, "const", "0.0", "(1.0)"),
        (21, "binop", "total += v * 2.0", "total -= v * 2.0"),
        (21, "binop", "v * 2.0", "(v / 2.0)"),
        (21, "const", "2.0", "(3.0)"),
    }
    assert found == expected  # no docstring, __all__, raise message or kernel-return mutant
    kernel_lines = {m.line for m in _mutants() if m.in_kernel}
    assert kernel_lines == {19, 21}
    assert {m.line for m in _mutants() if m.at_module_level} == {5}


def test_a_mutant_changes_exactly_its_segment_and_still_parses():
    lines = SOURCE.splitlines()
    for m in _mutants():
        text = mutate.apply(SOURCE, m)
        ast.parse(text)
        changed = [k + 1 for k, (a, b) in enumerate(zip(lines, text.splitlines())) if a != b]
        assert changed == [m.line], m
        assert m.mutated in text.splitlines()[m.line - 1]


def test_equivalent_entries_need_a_reason(tmp_path):
    good = tmp_path / "eq.txt"
    good.write_text("# comment\n\nlib/x.py:3:4 cmp   # the guard is redundant\n")
    assert mutate.load_equivalent(good) == {"lib/x.py:3:4 cmp": "the guard is redundant"}
    bad = tmp_path / "bad.txt"
    bad.write_text("lib/x.py:3:4 cmp\n")
    with pytest.raises(SystemExit, match="reason"):
        mutate.load_equivalent(bad)


def test_the_checked_in_equivalent_list_parses_and_names_configured_modules():
    import tomllib

    modules = set(tomllib.loads((_PATH.parent / "config.toml").read_text())["module"])
    for key in mutate.load_equivalent():
        assert key.split(":")[0] in modules, key


def test_the_score_counts_timeouts_as_kills_and_leaves_equivalents_out():
    m = _mutants()[0]
    outcomes = [mutate.Outcome(m, s, 1.0) for s in ("killed", "killed", "timeout", "survived", "equivalent")]
    score = mutate.summarise(outcomes)
    assert (score["mutants"], score["equivalent"], score["survived"]) == (5, 1, 1)
    assert score["killed_pct"] == 75.0


def test_each_mutant_has_its_own_key_even_in_a_chained_comparison():
    mutants = mutate.collect_mutants("m.py", "def g(x):\n    return 0.0 <= x < 1.0\n")
    keys = [m.key for m in mutants]
    assert len(keys) == len(set(keys))
    assert {"m.py:2:11 cmp", "m.py:2:11 cmp/1"} <= set(keys)
