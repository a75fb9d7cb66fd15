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
    good.write_text("# comment\n\nlib/x.py f cmp: if «x != x»: -> (x == x)   # a NaN never reaches f\n")
    assert mutate.load_equivalent(good) == {"lib/x.py f cmp: if «x != x»: -> (x == x)": "a NaN never reaches f"}
    bad = tmp_path / "bad.txt"
    bad.write_text("lib/x.py f cmp: if «x != x»: -> (x == x)\n")
    with pytest.raises(SystemExit, match="reason"):
        mutate.load_equivalent(bad)


def test_the_checked_in_equivalent_list_names_mutants_of_todays_code():
    """Every entry of equivalent.txt names a mutant that the runner plants in today's code
    (a stale entry is re-derived or dropped: see tests/mutation/README.md)."""
    import tomllib

    modules = tomllib.loads((_PATH.parent / "config.toml").read_text())["module"]
    root = _PATH.parents[2]
    equivalent = mutate.load_equivalent()
    assert {k.split(" ", 1)[0] for k in equivalent} <= set(modules)
    mutants = {path: mutate.collect_mutants(path, (root / path).read_text()) for path in modules}
    assert mutate.stale_entries(equivalent, mutants) == []


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
    assert {"m.py g cmp: return «0.0 <= x < 1.0» -> (0.0 < x < 1.0)",
            "m.py g cmp: return «0.0 <= x < 1.0» -> (0.0 <= x <= 1.0)"} <= set(keys)


def _keys(source: str) -> dict[str, int]:
    return {m.key: m.line for m in mutate.collect_mutants("m.py", source)}


def test_a_key_names_the_function_the_changed_text_and_its_neighbours_without_comments():
    keys = _keys("def f(a, b):\n    return a * b + LIMIT  # the product, raised\n")
    assert "m.py f binop: return «a * b» + LIMIT -> (a / b)" in keys
    assert "m.py f return: «return a * b + LIMIT» -> return None" in keys


def test_keys_stay_when_the_file_changes_elsewhere_and_change_with_the_mutated_line():
    keys = _keys(SOURCE)
    elsewhere = SOURCE.replace("LIMIT = 0.5\n", "LIMIT = 0.5\nOTHER = 2\n\n\ndef g(z):\n    return z - 1\n")
    moved = _keys(elsewhere)
    assert set(keys) <= set(moved)
    assert all(moved[k] == line + 5 for k, line in keys.items() if line > 5)  # same names, other lines
    edited = _keys(SOURCE.replace("max(x, y)", "max(x, y, 1)"))
    line_13 = {k for k in keys if keys[k] == 13}
    kept = {k for k in line_13 if k in edited}  # beyond four tokens of the edit: the same name
    assert kept == {"m.py f abs: return «abs(-x)» + max(x -> (-x)", "m.py f neg: return abs(«-x») + max( -> (x)"}


def test_the_same_text_twice_in_one_function_gets_numbered_keys():
    keys = _keys("def f(x):\n    if x:\n        return 0.0, 1.0\n    return 0.0, 1.0\n")
    assert {"m.py f const: return «0.0», 1.0 -> (1.0)", "m.py f const: return «0.0», 1.0 -> (1.0) [1]"} <= set(keys)


def test_a_stale_entry_is_named():
    mutants = {"m.py": mutate.collect_mutants("m.py", SOURCE)}
    live = mutants["m.py"][0].key
    assert mutate.stale_entries({live: "why", "m.py f cmp: «gone» -> (x)": "why", "n.py x": "other module"},
                                mutants) == ["m.py f cmp: «gone» -> (x)"]


def test_interpreted_applies_only_to_a_module_with_kernels():
    """``--interpreted`` (``make mutation``) runs a kernel module's mutants under NUMBA_DISABLE_JIT; a
    module without kernels runs compiled: interpreted, the rig physics tests that the actuator's
    mutants run took over the timeout, and each counted as a kill."""
    root = _PATH.parents[2]
    kernels = mutate.collect_mutants("lib/limit_set.py", (root / "lib/limit_set.py").read_text())
    plain = mutate.collect_mutants("lib/rig/actuator.py", (root / "lib/rig/actuator.py").read_text())
    assert mutate.runs_interpreted(kernels, True) and not mutate.runs_interpreted(kernels, False)
    assert not mutate.runs_interpreted(plain, True)
