"""The import layers of docs/architecture.md §9, checked over the source tree with ast.

More in docs/modules.md, `tests/unit/test_layering.py`.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

_NODES = frozenset({"nodes", "nodes.runtime", "nodes.devices", "nodes.recording", "nodes.tools"})

MAY_IMPORT: dict[str, frozenset[str]] = {
    "lib": frozenset({"lib"}),
    "messages": frozenset({"lib", "messages"}),
    "nodes.runtime": frozenset({"lib", "messages", "nodes.runtime"}),
    "nodes.devices": frozenset({"lib", "nodes.devices"}),
    "nodes.recording": frozenset({"lib", "messages", "nodes.runtime", "nodes.recording"}),
    "nodes": frozenset({"lib", "messages", "nodes.runtime", "nodes.devices", "nodes.recording", "nodes"}),
    "nodes.tools": frozenset({"lib", "messages"}) | _NODES,
    "launch": frozenset({"lib", "messages", "launch"}) | _NODES,
    "analysis": frozenset({"lib", "messages", "launch", "analysis"}) | _NODES,
    "cli": frozenset({"lib", "messages", "launch", "analysis", "cli"}) | _NODES,
}
"""Layer (a top-level package, or a folder of ``nodes``) → the layers it may import."""

_TOP = frozenset(name.split(".")[0] for name in MAY_IMPORT) - {"cli"}
_CLI = "launch/cli.py"

NO_ZMQ = ("lib", "messages")

ALLOWED: dict[tuple[str, str], str] = {}
"""(file, imported module) → why it is allowed for now."""

_MODULE_STRING = re.compile(r"^slipstack\.(\w+)(?:\.\w+)*(?::\w+)?$")


def _layer_of_path(path: Path) -> str:
    parts = path.relative_to(ROOT).parts
    if "/".join(parts) == _CLI:
        return "cli"
    if parts[0] == "nodes" and len(parts) > 2:
        return f"nodes.{parts[1]}"
    return parts[0]


def _layer_of_module(module: str) -> str | None:
    """The layer of ``slipstack.<package>…``; None for a module that is not ours."""
    parts = module.split(".")
    if parts[0] != "slipstack" or len(parts) < 2 or parts[1] not in _TOP:
        return None
    if ".".join(parts[1:3]) == "launch.cli":
        return "cli"
    if parts[1] == "nodes" and len(parts) > 2 and f"nodes.{parts[2]}" in _NODES:
        return f"nodes.{parts[2]}"
    return parts[1]


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(["slipstack", *parts])


def imported_modules(path: Path) -> set[str]:
    """Every absolute module name ``path`` imports (relative imports resolved), plus
    every ``slipstack.…`` module named in a string constant."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    package = _module_name(path).split(".")
    if path.name != "__init__.py":
        package = package[:-1]
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - node.level + 1]
                found.add(".".join(base + ([node.module] if node.module else [])))
            elif node.module:
                found.add(node.module)
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            named = _MODULE_STRING.match(node.value)
            if named and named.group(1) in _TOP:  # not a key such as "slipstack.clock"
                found.add(node.value.split(":")[0])
    return found


def _sources() -> list[Path]:
    return [p for pkg in sorted(_TOP) for p in sorted((ROOT / pkg).rglob("*.py"))]


def _layer_breaches() -> set[tuple[str, str]]:
    breaches = set()
    for path in _sources():
        own = _layer_of_path(path)
        for module in imported_modules(path):
            layer = _layer_of_module(module)
            if layer is not None and layer not in MAY_IMPORT[own]:
                breaches.add((str(path.relative_to(ROOT)), module))
    return breaches


def test_every_package_imports_only_the_layers_below_it():
    new = sorted(_layer_breaches() - set(ALLOWED))
    assert not new, (
        "imports against the layers of docs/architecture.md §9 (move the code down a layer, "
        "or the import up):\n" + "\n".join(f"{f} imports {m}" for f, m in new))


def test_the_allowlist_holds_only_breaches_that_still_exist():
    gone = sorted(set(ALLOWED) - _layer_breaches())
    assert not gone, "fixed, so remove from ALLOWED:\n" + "\n".join(f"{f}: {m}" for f, m in gone)


def test_lib_and_messages_never_import_zmq():
    offenders = sorted(
        f"{path.relative_to(ROOT)} imports {module}"
        for path in _sources() if _layer_of_path(path) in NO_ZMQ
        for module in imported_modules(path) if module.split(".")[0] == "zmq")
    assert not offenders, "lib/ and messages/ must stay free of sockets:\n" + "\n".join(offenders)


def test_the_checker_sees_relative_and_string_imports():
    probe = ROOT / "nodes" / "devices" / "backends.py"
    found = imported_modules(probe)
    assert "slipstack.nodes.devices.serial_link" in found  # ``from .serial_link import …``
    assert "slipstack.nodes.demo" in imported_modules(ROOT / "nodes" / "catalog.py")  # a string
    assert _layer_of_module("slipstack.nodes.runtime.host") == "nodes.runtime"
    assert _layer_of_module("slipstack.nodes.fusion") == "nodes"
    assert _layer_of_path(ROOT / "nodes" / "tools" / "topic_echo.py") == "nodes.tools"
    assert "nodes.tools" not in MAY_IMPORT["nodes"]  # a graph node never reaches for a CLI tool
