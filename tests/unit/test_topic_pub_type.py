"""``topic pub TOPIC [TYPE] VALUES``: the optional type as ``topic list -t`` prints it or by its short name."""

from __future__ import annotations

import pytest

from slipstack.lib.errors import ConfigError
from slipstack.messages import GripCommand
from slipstack.nodes.tools.topic_pub import split_type_and_values
from slipstack.nodes.tools.topic_tools import Endpoint, TopicInfo

GRIP = TopicInfo("grip/command", (GripCommand.TYPE,), (Endpoint("grip_controller", None),), ())


@pytest.mark.parametrize("word", ["slipstack/GripCommand", "GripCommand"])
def test_the_type_is_taken_off_the_values(word):
    cls, text = split_type_and_values(GRIP, [word, "{f_n_desired: 12.0}"])
    assert cls is GripCommand and text == "{f_n_desired: 12.0}"


@pytest.mark.parametrize("word", ["slipstack/Wrench", "Wrench"])
def test_another_type_than_the_topics_is_refused_by_name(word):
    with pytest.raises(ConfigError, match="grip/command carries slipstack/GripCommand, not slipstack/Wrench"):
        split_type_and_values(GRIP, [word, "{force: [1, 2, 3]}"])


def test_values_alone_are_the_values():
    assert split_type_and_values(GRIP, ["f_n_desired:", "12.0"]) == (GripCommand, "f_n_desired: 12.0")
