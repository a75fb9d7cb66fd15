"""docs/ stays true to the code: the equation table resolves, section citations exist.

- Every ``slipstack.…`` name in the equation table of docs/math.md (§7) imports, and
  every ``tests/…::test_name`` names a test function defined in that file.
- Every citation ``docs/<file>.md §N`` in the source tree (code, comments, docstrings,
  launch/scene files, README, docs) names a file in docs/ with a section numbered N.
- The design notes that are not part of the repository are cited nowhere.
"""

from __future__ import annotations

import ast
import importlib
import os
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SKIP_DIRS = {"__pycache__", "build", "dist", "runs", "node_modules"}
SOURCE_SUFFIXES = (".py", ".md", ".toml")

_TABLE_HEADING = re.compile(r"^## 7\. ", re.M)
_NAME = re.compile(r"`(slipstack(?:\.[A-Za-z_]\w*)+)`")
_TEST_ID = re.compile(r"`(tests/[\w/]+\.py)::(\w+)`")
_EQUATION = re.compile(r"^\| \((\d+)\) \|", re.M)
_CITATION = re.compile(r"docs/(\w+)\.md §(\d+(?:\.\d+)*)")
_SECTION = re.compile(r"^#{2,6} (\d+(?:\.\d+)*)\.? ", re.M)
_OUTSIDE_NOTES = re.compile(r"\b(?:MATH|ARCHITECTURE|PROTOCOLS|STYLE|CONVENTIONS)\.md\b|\bthe design notes\b"
                            r"|\bthe report on issue\b")


def _equation_table() -> str:
    """The text of docs/math.md from its §7 (the equation table) to the end."""
    text = (ROOT / "docs" / "math.md").read_text(encoding="utf-8")
    start = _TABLE_HEADING.search(text)
    assert start, "docs/math.md has no '## 7. ' section (the equation table)"
    return text[start.start():]


def _resolve(dotted: str) -> object:
    """Import the longest importable module prefix of ``dotted``, then walk attributes."""
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except ModuleNotFoundError:
            continue
        for attr in parts[cut:]:
            obj = getattr(obj, attr)  # AttributeError names what is missing
        return obj
    raise ModuleNotFoundError(dotted)


def _test_functions(path: Path) -> set[str]:
    """Names of the module-level and class-level test functions defined in ``path``."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    names = {n.name for n in tree.body if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))}
    for cls in (n for n in tree.body if isinstance(n, ast.ClassDef)):
        names |= {n.name for n in cls.body if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))}
    return {n for n in names if n.startswith("test")}


def _source_files() -> list[Path]:
    """Every .py, .md and .toml file of the working tree (hidden folders such as .venv,
    .git and build output left out)."""
    files = []
    for folder, subdirs, names in os.walk(ROOT):
        subdirs[:] = sorted(d for d in subdirs if not d.startswith(".") and d not in SKIP_DIRS
                            and not d.endswith(".egg-info"))
        files += [Path(folder) / n for n in sorted(names) if n.endswith(SOURCE_SUFFIXES)]
    return files


def _sections(doc: Path) -> set[str]:
    return set(_SECTION.findall(doc.read_text(encoding="utf-8")))


def _citation_problem(doc: str, section: str) -> str:
    """Why ``docs/<doc>.md §<section>`` does not resolve, or '' if it does."""
    target = ROOT / "docs" / f"{doc}.md"
    if not target.is_file():
        return "no such file"
    return "" if section in _sections(target) else "no such section"


def test_the_table_lists_every_numbered_equation_of_the_paper():
    listed = {int(n) for n in _EQUATION.findall(_equation_table())}
    assert listed == set(range(1, 15)), f"missing equations: {sorted(set(range(1, 15)) - listed)}"


def test_every_function_named_in_the_equation_table_imports():
    names = _NAME.findall(_equation_table())
    assert len(names) >= 20, "the equation table lost its function names"
    unresolved = []
    for dotted in names:
        try:
            obj = _resolve(dotted)
        except (ImportError, AttributeError) as exc:
            unresolved.append(f"{dotted}: {exc}")
            continue
        if not callable(obj):
            unresolved.append(f"{dotted}: not a function or class")
    assert not unresolved, "docs/math.md §7 names what does not exist:\n" + "\n".join(unresolved)


def test_every_test_named_in_the_equation_table_exists():
    ids = _TEST_ID.findall(_equation_table())
    assert len(ids) >= 20, "the equation table lost its test names"
    missing = []
    for rel, name in ids:
        path = ROOT / rel
        if not path.is_file():
            missing.append(f"{rel}: no such file")
        elif name not in _test_functions(path):
            missing.append(f"{rel}::{name}: no such test")
    assert not missing, "docs/math.md §7 names tests that do not exist:\n" + "\n".join(missing)


def test_every_cited_docs_section_exists():
    citations: dict[tuple[str, str], list[str]] = {}
    for path in _source_files():
        for lineno, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            for doc, section in _CITATION.findall(line):
                citations.setdefault((doc, section), []).append(f"{path.relative_to(ROOT)}:{lineno}")
    assert citations, "no docs/<file>.md §N citation found: is the pattern still right?"
    broken = [f"docs/{doc}.md §{section} ({problem}), cited at {', '.join(where)}"
              for (doc, section), where in sorted(citations.items())
              if (problem := _citation_problem(doc, section))]
    assert not broken, "citations into docs/ that do not resolve:\n" + "\n".join(broken)


def test_no_design_note_outside_the_repository_is_cited():
    here = Path(__file__).resolve()
    cited = [f"{p.relative_to(ROOT)}:{i}" for p in _source_files() if p.resolve() != here
             for i, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1) if _OUTSIDE_NOTES.search(line)]
    assert not cited, "cite docs/ instead of design notes that a clone does not have:\n" + "\n".join(cited)


@pytest.mark.parametrize("doc", ["architecture", "math", "protocols"])
def test_each_design_document_numbers_its_sections(doc):
    sections = _sections(ROOT / "docs" / f"{doc}.md")
    assert {"1", "2", "3"} <= sections, f"docs/{doc}.md: sections must be numbered '## 1. Title'"
