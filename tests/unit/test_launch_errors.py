"""Every error path of the launch-file loader and the launcher's wiring says what is wrong.

Each test writes a small launch file and asserts the ConfigError's message,
or the safe outcome for inputs that used to be read wrongly.
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import pytest

from slipstack.launch.cli import main
from slipstack.launch.launch_file import launch_files_dir, load_launch_file
from slipstack.lib.errors import ConfigError

BUILTINS = {"run_dir": "/tmp/slipstack-test"}
SOURCE = '[[node]]\nname = "source"\ntype = "wrench_source"\n'


def _load(tmp_path: Path, text: str, overrides: dict[str, str] | None = None, name: str = "t.toml"):
    path = tmp_path / name
    path.write_text(text)
    return load_launch_file(str(path), overrides, builtins=BUILTINS)


@pytest.mark.parametrize("text, message", [
    (SOURCE + "colour = 'red'\n", r"node\[0\]: unknown key\(s\) \['colour'\]; allowed: "),
    ('[[node]]\nname = "x"\n', r"node\[0\]: missing 'type'"),
    (SOURCE + SOURCE, r"node names must be unique; repeated: \['source'\]"),
    (SOURCE + 'after = ["rig"]\n', r"node source starts after \['rig'\], which this launch does not run"),
    ('[launch]\ndurration_s = 1\n' + SOURCE, r"\[launch\]: unknown key\(s\) \['durration_s'\]"),
    ('[nodes]\nname = "x"\n', r"unknown section\(s\) \['nodes'\]"),
    ('node = "source"\n', r"'node' must be an array of tables"),
    (SOURCE + 'respawn_delay_s = "soon"\n', r"respawn_delay_s: must be a number, got 'soon'"),
    (SOURCE + 'respawn_max_retries = 1.5\n', r"respawn_max_retries: must be an integer, got 1.5"),
    (SOURCE + 'respawn_reset_s = -1\n', r"respawn_reset_s: must be >= 0, got -1"),
    (SOURCE + 'realtime_priority = 100\n', r"realtime_priority: must be <= 99, got 100"),
    (SOURCE + 'realtime_priority = -1\n', r"realtime_priority: must be >= 0, got -1"),
    (SOURCE + 'transport = "udp"\n', r"transport must be 'ipc' or 'tcp'; got 'udp'"),
    (SOURCE + 'params = "fast"\n', r"params must be a table"),
    (SOURCE + 'after = "rig"\n', r"after must be a list of node names"),
    (SOURCE + 'params = { rate_hz = "$(rate)" }\n', r"unknown launch argument \$\(rate\); declared: "),
    ('[args]\nrate = "$(speed)"\n' + SOURCE, r"args.rate: unknown launch argument \$\(speed\)"),
])
def test_a_wrong_launch_file_names_what_is_wrong(tmp_path, text, message):
    with pytest.raises(ConfigError, match=message):
        _load(tmp_path, text)


@pytest.mark.parametrize("key, value", [
    ("name", "../../escape"), ("name", "a/b"), ("name", ""), ("name", ".hidden"), ("container", "../ctl"),
])
def test_node_and_container_names_that_are_not_safe_identifiers_are_refused(tmp_path, key, value):
    text = f'[[node]]\ntype = "relay"\n{key} = {json.dumps(value)}\n'
    with pytest.raises(ConfigError, match=rf"{key} must be letters, digits, _ and - only"):
        _load(tmp_path, text)


def test_names_with_digits_dashes_and_underscores_are_fine(tmp_path):
    lf = _load(tmp_path, '[[node]]\ntype = "relay"\nname = "relay_2-b"\ncontainer = "pipe-1"\n')
    assert [(e.name, e.container) for e in lf.nodes] == [("relay_2-b", "pipe-1")]


def test_extends_loops_are_named(tmp_path):
    (tmp_path / "a.toml").write_text('[launch]\nextends = "./b.toml"\n')
    (tmp_path / "b.toml").write_text('[launch]\nextends = "./a.toml"\n')
    with pytest.raises(ConfigError, match=r"a.toml: 'extends' loops back to itself: a.toml -> b.toml -> a.toml"):
        load_launch_file(str(tmp_path / "a.toml"), builtins=BUILTINS)


def test_unknown_argument_and_bad_argument_types_are_refused():
    with pytest.raises(ConfigError, match=r"demo.toml: no launch argument 'bogus'; declared: container, "):
        load_launch_file("demo", {"bogus": "1"}, builtins=BUILTINS)
    with pytest.raises(ConfigError, match=r"launch argument rate_hz: must be a number, got 'fast'"):
        load_launch_file("demo", {"rate_hz": "fast"}, builtins=BUILTINS)
    with pytest.raises(ConfigError, match=r"launch argument respawn: must be true or false, got 'maybe'"):
        load_launch_file("demo", {"respawn": "maybe"}, builtins=BUILTINS)


@pytest.mark.parametrize("text", ["nan", "inf", "-inf", "NaN"])
def test_a_non_finite_number_argument_is_refused(text):
    """Like ``ft_rate_hz:=nan`` on a paper scene."""
    with pytest.raises(ConfigError, match=rf"launch argument rate_hz: must be finite, got '{text}'"):
        load_launch_file("demo", {"rate_hz": text}, builtins=BUILTINS)


@pytest.mark.parametrize("args, message", [
    ('a = "$(a)"', r"launch argument a refers to itself: a -> a"),
    ('a = "x$(b)"\nb = "$(a)y"', r"launch argument a refers to itself: a -> b -> a"),
    ('a = "$(a)$(a)"', r"launch argument a refers to itself"),
])
def test_self_referring_arguments_are_refused(tmp_path, args, message):
    with pytest.raises(ConfigError, match=message):
        _load(tmp_path, f"[args]\n{args}\n" + SOURCE)


def test_arguments_that_double_each_other_are_stopped_at_a_bounded_length(tmp_path):
    """Thirty arguments, each twice the one before: 2**30 characters unless bounded."""
    lines = ['a0 = "xx"'] + [f'a{k} = "$(a{k - 1})$(a{k - 1})"' for k in range(1, 30)]
    with pytest.raises(ConfigError, match=r"gives \d+ characters \(more than 65536\); does an argument repeat"):
        _load(tmp_path, "[args]\n" + "\n".join(lines) + "\n" + SOURCE)


def test_arguments_may_refer_to_arguments_in_any_order(tmp_path):
    lf = _load(tmp_path, '[args]\nurl = "rdt://$(host):$(port)"\nport = "$(base)"\nbase = 49152\nhost = "h"\n' + SOURCE)
    assert lf.args["url"] == "rdt://h:49152" and lf.args["port"] == 49152


@pytest.mark.parametrize("value, enabled", [
    ('"false"', False), ('"False"', False), ('"true"', True), ("false", False), ("true", True),
])
def test_enabled_as_a_string_means_what_it_says(tmp_path, value, enabled):
    lf = _load(tmp_path, SOURCE + f"enabled = {value}\n")
    assert bool(lf.nodes) is enabled


@pytest.mark.parametrize("key", ["enabled", "respawn", "required", "stop_first", "respawn_standby"])
def test_a_flag_that_is_neither_true_nor_false_is_refused(tmp_path, key):
    with pytest.raises(ConfigError, match=rf"{key}: must be true or false, got 'often'"):
        _load(tmp_path, SOURCE + f'{key} = "often"\n')


def test_a_flag_from_a_string_argument_is_read_too(tmp_path):
    lf = _load(tmp_path, '[args]\non = "false"\n' + SOURCE + 'enabled = "$(on)"\n')
    assert lf.nodes == []


def test_container_members_must_agree_on_their_process_settings(tmp_path):
    text = ('[[node]]\nname = "relay"\ntype = "relay"\ncontainer = "c"\nrespawn = true\n'
            '[[node]]\nname = "sink"\ntype = "sink"\ncontainer = "c"\n')
    with pytest.raises(ConfigError, match=r"nodes relay and sink share container 'c' but differ in respawn"):
        _load(tmp_path, text)
    with pytest.raises(ConfigError, match=r"container 'relay' has the name of a node"):
        _load(tmp_path, '[[node]]\nname = "relay"\ntype = "relay"\ncontainer = "relay"\n')


def test_after_constraints_that_form_a_cycle_are_named(tmp_path):
    from slipstack.launch.launcher import Launcher

    lf = _load(tmp_path, '[[node]]\nname = "relay"\ntype = "relay"\nafter = ["sink"]\n'
                         '[[node]]\nname = "sink"\ntype = "sink"\nafter = ["relay"]\n')
    with pytest.raises(ConfigError, match=r"'after' constraints form a cycle among \['relay', 'sink'\]|"
                                          r"'after' constraints form a cycle among \['sink', 'relay'\]"):
        Launcher(lf, tmp_path, echo=lambda line: None)


@pytest.mark.parametrize("stray", ["fig15", "fig15.toml", "stack.toml"])
def test_a_stray_file_in_the_current_directory_does_not_shadow_a_shipped_one(tmp_path, monkeypatch, stray):
    (tmp_path / stray).write_text('[launch]\ndescription = "impostor"\n[[node]]\ntype = "sink"\n')
    monkeypatch.chdir(tmp_path)
    lf = load_launch_file("fig15", builtins=BUILTINS)
    assert lf.path == launch_files_dir() / "fig15.toml"
    assert lf.description.startswith("Fig. 15") and "rig" in {e.type for e in lf.nodes}


def test_a_file_of_your_own_is_named_as_a_path(tmp_path, monkeypatch):
    (tmp_path / "fig15.toml").write_text('[launch]\ndescription = "mine"\n[[node]]\ntype = "sink"\n')
    (tmp_path / "mine").write_text('[launch]\ndescription = "mine"\n[[node]]\ntype = "sink"\n')
    monkeypatch.chdir(tmp_path)
    assert load_launch_file("./fig15.toml", builtins=BUILTINS).description == "mine"
    with pytest.raises(ConfigError, match=r"cannot find 'mine' .*give a path, e.g. ./mine"):
        load_launch_file("mine", builtins=BUILTINS)
    assert load_launch_file("./mine", builtins=BUILTINS).description == "mine"


def test_extends_takes_the_shipped_base_even_beside_a_stray_copy(tmp_path):
    (tmp_path / "stack.toml").write_text('[launch]\ndescription = "impostor"\n')
    lf = _load(tmp_path, '[launch]\nextends = "stack.toml"\n', name="mine.toml")
    assert "rig" in {e.type for e in lf.nodes}


def test_check_is_a_launch_key_and_an_argument():
    assert load_launch_file("demo", builtins=BUILTINS).check is False
    assert load_launch_file("demo", {"check": "true"}, builtins=BUILTINS).check is True
    with pytest.raises(ConfigError, match=r"launch argument check: must be true or false, got 'often'"):
        load_launch_file("demo", {"check": "often"}, builtins=BUILTINS)


MALFORMED = {
    "unclosed_table": ('[[node]\ntype = "sink"\n', r":1:\d+: not valid TOML: "),
    "missing_value": ('[[node]]\ntype = "sink"\nname =\n', r":3:\d+: not valid TOML: "),
    "bad_string": ('[launch]\ndescription = "unterminated\n', r":2:\d+: not valid TOML: "),
    "duplicate_key": ('[[node]]\ntype = "sink"\ntype = "relay"\n', r":3:\d+: not valid TOML: "),
    "node_string": ('node = "sink"\n', r"'node' must be an array of tables"),
    "args_string": ('args = "x"\n', r"\[args\] must be a table"),
    "launch_string": ('launch = 3\n', r"\[launch\] must be a table"),
    "delay_string": ('[[node]]\ntype = "sink"\nrespawn_delay_s = "x"\n', r"respawn_delay_s: must be a number"),
    "extends_number": ('[launch]\nextends = 3\n', r"extends must be a file name"),
    "binary": (b"\xff\xfe\x00junk", r"cannot read it"),
}


@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_a_malformed_file_gives_one_line_and_leaves_no_run_directory(tmp_path, monkeypatch, capsys, case):
    text, message = MALFORMED[case]
    root = tmp_path / "root"
    monkeypatch.setenv("SLIPSTACK_RUN_ROOT", str(root))
    bad = tmp_path / f"{case}.toml"
    bad.write_bytes(text if isinstance(text, bytes) else text.encode())
    assert main(["launch", str(bad)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1, err
    assert err.startswith("slipstack launch: ") and bad.name in err, err
    assert re.search(message, err), err
    assert [p.name for p in root.iterdir()] == [], "a run directory was left behind"


def test_a_recording_that_exists_is_refused_and_kept(tmp_path):
    from slipstack.nodes.recording.recorder import Recorder, RecorderParams

    existing = tmp_path / "take1.mcap"
    existing.write_bytes(b"precious")
    with pytest.raises(ConfigError, match=r"take1.mcap exists; pass recording:=NEW.mcap .* or delete it"):
        Recorder(RecorderParams(path=str(existing))).start(None)
    assert existing.read_bytes() == b"precious"
    assert os.listdir(tmp_path) == ["take1.mcap"]


def test_a_recording_the_recorder_cannot_write_is_refused_with_what_to_do(tmp_path):
    from slipstack.nodes.recording.recorder import Recorder, RecorderParams

    (tmp_path / "a_file").write_text("not a folder")
    with pytest.raises(ConfigError, match=r"cannot write the recording .*run.mcap .* in a folder you may write"):
        Recorder(RecorderParams(path=str(tmp_path / "a_file" / "run.mcap"))).start(None)
