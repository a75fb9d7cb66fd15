"""The import layers of docs/architecture.md §9, checked over the source tree with ast.

Lowest first: ``lib`` imports nothing of ours but ``lib``; ``messages`` imports ``lib``;
``nodes`` imports ``lib`` and ``messages``; ``analysis`` imports those and ``nodes``;
``launch`` is the top and may import anything. ``lib`` and ``messages`` never import
zmq. An import counts wherever it is written (module level or inside a function), and
so does a module named in a string (``importlib.import_module("slipstack.x.y")``, the
node catalog's ``"slipstack.nodes.demo:Relay"``).

Today's violations are listed one by one in :data:`ALLOWED`; a new one fails the test,
and an entry that no longer occurs fails it too, so the list only shrinks.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

MAY_IMPORT: dict[str, frozenset[str]] = {
    "lib": frozenset({"lib"}),
    "messages": frozenset({"lib", "messages"}),
    "nodes": frozenset({"lib", "messages", "nodes"}),
    "analysis": frozenset({"lib", "messages", "nodes", "analysis"}),
    "launch": frozenset({"lib", "messages", "nodes", "analysis", "launch"}),
}
"""Package → the packages of ours it may import."""

NO_ZMQ = ("lib", "messages")

ALLOWED: dict[tuple[str, str], str] = {
    ("nodes/rig.py", "slipstack.launch.launch_file"):
        "resolve_path finds a shipped scene by name; issue 11: to move",
    ("nodes/lockstep.py", "slipstack.launch.launch_file"):
        "resolve_path finds a shipped scene by name; issue 11: to move",
    ("nodes/material_param.py", "slipstack.launch.launch_file"):
        "resolve_path finds a shipped material by name; issue 11: to move",
}
"""(file, imported module) → why it is allowed for now."""

_MODULE_STRING = re.compile(r"^slipstack\.(\w+)(?:\.\w+)*(?::\w+)?$")


def _package_of(path: Path) -> str:
    return path.relative_to(ROOT).parts[0]


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
            if named and named.group(1) in MAY_IMPORT:  # not a key such as "slipstack.clock"
                found.add(node.value.split(":")[0])
    return found


def _sources() -> list[Path]:
    return [p for pkg in MAY_IMPORT for p in sorted((ROOT / pkg).rglob("*.py"))]


def _layer_breaches() -> set[tuple[str, str]]:
    breaches = set()
    for path in _sources():
        own = _package_of(path)
        for module in imported_modules(path):
            parts = module.split(".")
            if parts[0] == "slipstack" and len(parts) > 1 and parts[1] not in MAY_IMPORT[own]:
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
        for path in _sources() if _package_of(path) in NO_ZMQ
        for module in imported_modules(path) if module.split(".")[0] == "zmq")
    assert not offenders, "lib/ and messages/ must stay free of sockets:\n" + "\n".join(offenders)


def test_the_checker_sees_relative_and_string_imports():
    probe = ROOT / "nodes" / "devices" / "backends.py"
    found = imported_modules(probe)
    assert "slipstack.nodes.devices.serial_link" in found  # ``from .serial_link import …``
    assert "slipstack.nodes.demo" in imported_modules(ROOT / "nodes" / "catalog.py")  # a string
    assert ("nodes/rig.py", "slipstack.launch.launch_file") in _layer_breaches()
