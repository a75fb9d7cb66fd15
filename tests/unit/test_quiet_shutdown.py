"""The quiet end of a simulated run under ``--log-level``: the world's end of scene is seen
by the launcher whatever level the operator asked for (``launch/quiet_shutdown.py``)."""

from __future__ import annotations

import logging

from slipstack.launch.quiet_shutdown import WorldEndFilter, WorldLogLevels
from slipstack.nodes.runtime.logs import parse_log_levels

DOCS_LEVELS = "warning,monitor=info"  # docs/operating.md's example


def test_the_world_logs_its_end_of_scene_under_warning_and_the_launcher_hides_it():
    levels = WorldLogLevels(DOCS_LEVELS, {"rig": ("rig",)})
    default, per_node = parse_log_levels(levels.spec_for("rig"))  # what the rig's process runs with
    assert per_node.get("rig", default) == logging.INFO  # it writes its end of scene for the launcher
    line = "scene default finished"
    ended = WorldEndFilter({"rig"}, {"ft_driver"})
    assert ended.keep("rig", line) and not levels.shown("rig", line)  # seen, not shown (info < warning)
    retry = "error: rdt://127.0.0.1:5000: [Errno 111] Connection refused; retrying"
    assert not ended.keep("ft_driver", retry)  # the drivers' aftermath is held


def test_levels_of_the_world_follow_what_was_asked():
    levels = WorldLogLevels(DOCS_LEVELS, {"rig": ("rig",)})
    assert levels.shown("rig", "warning: rig fell behind") and levels.shown("rig", "error: x")
    assert levels.shown("monitor", "STATUS ...")  # not the world: the node filters itself
    assert levels.spec_for("monitor") == DOCS_LEVELS
    assert WorldLogLevels("", {"rig": ("rig",)}).spec_for("rig") == ""
    debug = WorldLogLevels("warning,rig=debug", {"rig": ("rig",)})
    assert debug.spec_for("rig") == "warning,rig=debug" and debug.shown("rig", "debug: tick")
