"""Read the YAML values a user types on the command line (``topic pub``), with PyYAML.

Flow or block style, as ``ros2 topic pub`` takes them::

    {f_n_desired: 12.0, law: manual}
    force: [1.5, 0, -2e-3], status: "ok, really"      # outer braces may be left out

More in docs/modules.md, `nodes/tools/topic_yaml.py`.
"""

from __future__ import annotations

import re
from typing import Any

import yaml

from slipstack.lib.errors import ConfigError

__all__ = ["parse_flow"]

_BOOL = re.compile(r"^(?:true|True|TRUE|false|False|FALSE)$")
_NULL = re.compile(r"^(?:~|null|Null|NULL|)$")
_INT = re.compile(r"^(?:[-+]?[0-9]+|0o[0-7]+|0x[0-9a-fA-F]+)$")
_FLOAT = re.compile(r"^(?:[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?"
                    r"|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$")


_BARE_MAPPING = re.compile(r"^[^,\[\]{}]*?:(\s|$)")


class _CoreLoader(yaml.SafeLoader):
    """SafeLoader with YAML 1.2 core-schema scalars, unique string keys and no aliases."""

    yaml_implicit_resolvers: dict = {}

    def compose_node(self, parent: Any, index: Any) -> Any:
        if self.check_event(yaml.AliasEvent):
            mark = self.peek_event().start_mark
            raise yaml.MarkedYAMLError(None, None, "aliases (*name) are not allowed", mark)
        return super().compose_node(parent, index)

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for key_node, value_node in node.value:
            key = self.construct_object(key_node, deep=deep)
            if not isinstance(key, str) or not key:
                raise yaml.MarkedYAMLError(None, None, f"a key must be a field name, got {key!r}",
                                           key_node.start_mark)
            if key in out:
                raise yaml.MarkedYAMLError(None, None, f"key {key!r} given twice", key_node.start_mark)
            out[key] = self.construct_object(value_node, deep=deep)
        return out

    def construct_yaml_int(self, node: yaml.ScalarNode) -> int:
        value = self.construct_scalar(node)
        return int(value, 0) if value[:2] in ("0x", "0o") else int(value)


_CoreLoader.add_constructor("tag:yaml.org,2002:map", _CoreLoader.construct_mapping)
_CoreLoader.add_constructor("tag:yaml.org,2002:int", _CoreLoader.construct_yaml_int)
for _tag, _pattern, _first in (("bool", _BOOL, "tTfF"), ("null", _NULL, "~nN"), ("int", _INT, "-+0123456789"),
                               ("float", _FLOAT, "-+0123456789.")):
    _CoreLoader.add_implicit_resolver(f"tag:yaml.org,2002:{_tag}", _pattern, list(_first) + ([""] if _tag == "null" else []))


def parse_flow(text: str) -> Any:
    """Parse the values typed on the command line (module docstring); empty text is ``{}``;
    one line of ``key: value, …`` is read as a mapping.

    Raises:
        ConfigError: the text is not YAML as read here (says where and what).
    """
    stripped = text.strip()
    if not stripped:
        return {}
    if "\n" not in stripped and stripped[0] not in "{[\"'" and _BARE_MAPPING.match(stripped):
        text = "{" + stripped + "}"  # `a: 1, b: [2]` on one line: a flow mapping without its braces
    try:
        return yaml.load(text, Loader=_CoreLoader)  # noqa: S506 — a SafeLoader subclass
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        where = f" at character {mark.index + 1}" if mark is not None else ""
        raise ConfigError(f"cannot read {text!r}{where}: {exc.problem or exc.context}") from None
    except yaml.YAMLError as exc:
        raise ConfigError(f"cannot read {text!r}: {exc}") from None
