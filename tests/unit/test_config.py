"""lib/config.py: typed reading of loose values, one error wording for files and URLs."""

from __future__ import annotations

import pytest

import math

from slipstack.lib.config import ConfigTable, read_flag, read_number, read_typed
from slipstack.lib.errors import ConfigError


def test_a_toml_table_is_read_typed_and_strictly():
    t = ConfigTable({"mu": 0.5, "n": 3, "name": "pad", "on": True, "v": [1, 2, 3], "sub": {"x": 1.0}}, "contact", "s.toml")
    assert (t.real("mu", lo=0.0), t.integer("n"), t.text("name"), t.flag("on")) == (0.5, 3, "pad", True)
    assert t.vector("v", 3) == (1.0, 2.0, 3.0) and t.real("absent", 7.0) == 7.0
    sub = t.table("sub")
    assert sub.real("x") == 1.0
    sub.finish()
    t.finish()


@pytest.mark.parametrize("data, read, message", [
    ({"mu": "0.5"}, lambda t: t.real("mu"), "s.toml: contact.mu: must be a number, got '0.5'"),
    ({"mu": -1}, lambda t: t.real("mu", lo=0.0), "s.toml: contact.mu: must be >= 0.0, got -1"),
    ({"n": True}, lambda t: t.integer("n"), "s.toml: contact.n: must be an integer, got True"),
    ({"on": "yes"}, lambda t: t.flag("on"), "s.toml: contact.on: must be true or false, got 'yes'"),
    ({}, lambda t: t.real("mu"), "s.toml: contact.mu: missing required key"),
    ({"mu": 1.0, "mu_z": 1}, lambda t: (t.real("mu"), t.finish()), "s.toml: contact.mu_z: unknown key; known here: mu"),
])
def test_file_errors_name_source_key_and_what_is_wrong(data, read, message):
    with pytest.raises(ConfigError) as exc:
        read(ConfigTable(data, "contact", "s.toml"))
    assert str(exc.value) == message


def test_text_values_are_parsed_and_refused_in_the_same_words():
    t = ConfigTable({"rate_hz": "500", "baud": "9600", "rle": "on", "x": "1.5e3"}, "", "dev://a", from_text=True)
    assert (t.real("rate_hz"), t.integer("baud"), t.flag("rle"), t.real("x")) == (500.0, 9600, True, 1500.0)
    bad = ConfigTable({"baud": "96.5", "rate_hz": "nan"}, "", "dev://a", from_text=True)
    with pytest.raises(ConfigError, match=r"^dev://a: baud: must be an integer, got '96.5'$"):
        bad.integer("baud")
    with pytest.raises(ConfigError, match=r"^dev://a: rate_hz: must be finite, got 'nan'$"):
        bad.real("rate_hz")


def test_one_value_is_read_by_its_type_hint():
    assert read_typed("0.25", float, "p.x") == 0.25 and math.isnan(read_typed("nan", float, "p.x"))
    assert read_typed("3", int, "p.n") == 3 and read_typed(4.0, int, "p.n") == 4
    assert read_typed("a,b", list[str], "p.l") == ["a", "b"] and read_typed([1, "2"], tuple[int, ...], "p.t") == (1, 2)
    assert read_typed("none", float | None, "p.o") is None and read_typed("Off", bool, "p.b") is False
    for value, hint, message in [("x", float, "p.x: must be a number, got 'x'"),
                                 (1.5, int, "p.n: must be an integer, got 1.5"),
                                 ("inf", int, "p.n: must be an integer, got 'inf'"),
                                 ("often", bool, "p.b: must be true or false, got 'often'"),
                                 ({"a": 1}, str, "p.s: must be a string, got {'a': 1}")]:
        with pytest.raises(ConfigError) as exc:
            read_typed(value, hint, message.split(":")[0])
        assert str(exc.value) == message


def test_flags_and_numbers_share_one_vocabulary():
    assert [read_flag(w, "f") for w in ("true", "YES", "1", "on", " false ", "no", "0", "off")] == [True] * 4 + [False] * 4
    with pytest.raises(ConfigError, match=r"^f: must be true or false, got 'yes'$"):
        read_flag("yes", "f", from_text=False)
    with pytest.raises(ConfigError, match=r"^launch argument rate_hz: must be finite, got 'inf'$"):
        read_number("inf", "launch argument rate_hz")
    assert read_number("-3", "n", int, lo=-20) == -3


def test_node_parameters_are_read_in_the_same_words():
    from slipstack.nodes.cor_estimator import CorParams
    from slipstack.nodes.runtime.node import make_params

    p = make_params(CorParams, {"pool": "2", "warm_start": "off", "paper_gain": "0.3"}, "cor_estimator")
    assert (p.pool, p.warm_start, p.paper_gain) == (2, False, 0.3)
    with pytest.raises(ConfigError, match=r"^cor_estimator\.pool: must be an integer, got 'two'$"):
        make_params(CorParams, {"pool": "two"}, "cor_estimator")


def test_parameter_values_are_shown_as_a_launch_file_writes_them():
    """``param get/list`` and ``launch --show-args`` show TOML (a value ``param set`` stored as
    text was shown quoted, '3.0', 'nan'); what they show reads back as the same value."""
    import math
    import tomllib

    from slipstack.lib.toml_file import toml_value
    from slipstack.nodes.slip_detector import SlipDetector
    from slipstack.nodes.tools.param_tools import _values

    shown = {name: value for name, (value, _) in _values(SlipDetector, {"mu": "3.0", "delta": "nan"}).items()}
    assert (shown["mu"], shown["delta"], shown["method"]) == ("3.0", "nan", '"exact"')
    assert shown["gamma_release"] == "nan" and shown["also"].startswith("[")  # defaults alike
    for value in (True, 3.0, -0.25, 7, 1e-9, "a \"quoted\" \\ path\n", [1.0, 2.0], ["x", "y"], {"a": 1}):
        assert tomllib.loads(f"v = {toml_value(value)}")["v"] == value, value
    assert math.isnan(tomllib.loads(f"v = {toml_value(math.nan)}")["v"])
    assert tomllib.loads(f"v = {toml_value(-math.inf)}")["v"] == -math.inf
