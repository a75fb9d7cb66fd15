"""lib/config.py: typed reading of loose values, one error wording for files and URLs."""

from __future__ import annotations

import pytest

from slipstack.lib.config import ConfigTable
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
    ({"mu": -1}, lambda t: t.real("mu", lo=0.0), "s.toml: contact.mu: must be >= 0.0, got -1.0"),
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
    with pytest.raises(ConfigError, match=r"^dev://a: rate_hz: must be finite, got nan$"):
        bad.real("rate_hz")
