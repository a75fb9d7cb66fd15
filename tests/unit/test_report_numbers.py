"""Every number in ``slipstack reproduce``'s report is computed: none is written into its text by hand.

The report's words are the ``paper``, ``ours``, ``differences`` and ``table`` of each
``FigureText`` the figure modules return. This test reads those modules' source and
follows what flows into those fields (string literals, f-strings, the local variables and
the module's own functions they use): a literal digit there is a number typed by hand,
unless it is a name (an equation "(11)", a figure "Fig. 4a", a section "§3.1", a reference
"[9]", a percentile "p95", an experiment "fig15") or the 0 and 1 of a formula ("γ > 1",
"1 − δ", "0/1", "f_t = 0").
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ANALYSIS = Path(__file__).resolve().parents[2] / "analysis"
MODULES = ["measured.py", "figures.py", "figures_control.py", "figures_detection.py", "sensitivity.py", "beyond.py"]
TEXT_FIELDS = (3, 4, 5, 6)  # FigureText(key, title, png, paper, ours, differences, table)
TEXT_KEYWORDS = {"paper", "ours", "differences", "table"}

NAMES = [
    r"\((?:1[0-4]|[1-9])\)",  # an equation of the paper
    r"Figs?\. \d+[a-e]?(?:[–-]\d+[a-e]?)?(?:(?:,| and) \d+[a-e]?)*",  # its figures
    r"§\d+(?:\.\d+)?",  # a section of docs/math.md
    r"\[\d+\]",  # a reference of the paper
    r"\bp\d{1,2}\b",  # a percentile's name
    r"\b[01]/1\b",  # a 0/1 trace
    r"(?:γ|τ_t|\|n\|)\s*(?:>|≤|<|≥|=)\s*1\b",  # the test's threshold
    r"\b1\s*[−-]\s*(?:δ|γ)",  # 1 − δ, 1 − γ
    r"\b1/(?:σ|N_A|μ|β|d_s)",  # inverse symbols
    r"\b0\s*(?::|,)\s*(?=stick)",  # "0: stick"
    r"1: slip",
    r"max\(delay, 0\)",
    r"\bf_t = 0\b",  # a pure torque
    r"\bminus 1\b",  # a ratio's error
    r"\b1 / 5 min\b",  # the load average's windows
    r"\bfig\d+\w*",  # an experiment's name
    r"\bCorrection \d\b",  # a section of the report
    r"^C\d$",  # a colour in a drawing helper
]
HAND_WRITTEN = re.compile(r"\d")


def _strip_names(text: str) -> str:
    for pattern in NAMES:
        text = re.sub(pattern, "", text)
    return text


class _Texts(ast.NodeVisitor):
    """The string literals that reach a FigureText's words, per module."""

    def __init__(self, tree: ast.Module) -> None:
        self.functions = {n.name: n for n in tree.body if isinstance(n, ast.FunctionDef)}
        self.assigns = {n.targets[0].id: n.value for n in tree.body
                        if isinstance(n, ast.Assign) and isinstance(n.targets[0], ast.Name)}
        self.found: list[tuple[int, str]] = []
        self._seen: set[int] = set()

    def visit_Call(self, node: ast.Call) -> None:
        if isinstance(node.func, ast.Name) and node.func.id == "FigureText":
            args = [a for i, a in enumerate(node.args) if i in TEXT_FIELDS]
            args += [k.value for k in node.keywords if k.arg in TEXT_KEYWORDS]
            function = self._enclosing(node)
            for arg in args:
                self._follow(arg, function)
        self.generic_visit(node)

    def _enclosing(self, node: ast.AST) -> ast.FunctionDef | None:
        for f in self.functions.values():
            if f.lineno <= node.lineno <= (f.end_lineno or f.lineno):
                return f
        return None

    def _follow(self, node: ast.AST, function: ast.FunctionDef | None) -> None:
        if id(node) in self._seen:
            return
        self._seen.add(id(node))
        skip = {id(part) for sub in ast.walk(node) if isinstance(sub, ast.FormattedValue) and sub.format_spec
                for part in ast.walk(sub.format_spec)}  # ":.2f" is a format, not a number
        skip |= {id(f.body[0].value) for f in ast.walk(node) if isinstance(f, ast.FunctionDef)
                 and f.body and isinstance(f.body[0], ast.Expr) and isinstance(f.body[0].value, ast.Constant)}
        for sub in ast.walk(node):
            if id(sub) in skip:
                continue
            if isinstance(sub, ast.Constant) and isinstance(sub.value, str):
                self.found.append((sub.lineno, sub.value))
            elif isinstance(sub, ast.Name):
                self._follow_name(sub.id, function)
            elif isinstance(sub, ast.Call) and isinstance(sub.func, ast.Name) and sub.func.id in self.functions:
                self._follow(self.functions[sub.func.id], None)

    def _follow_name(self, name: str, function: ast.FunctionDef | None) -> None:
        if function is not None:
            for n in ast.walk(function):
                if isinstance(n, ast.Assign) and any(isinstance(t, ast.Name) and t.id == name for t in n.targets):
                    self._follow(n.value, function)
        if name in self.assigns:
            self._follow(self.assigns[name], None)
        if name in self.functions:
            self._follow(self.functions[name], None)


def _hand_written(module: str) -> list[str]:
    tree = ast.parse((ANALYSIS / module).read_text(), module)
    texts = _Texts(tree)
    texts.visit(tree)
    return [f"{module}:{lineno}: {text!r}" for lineno, text in texts.found if HAND_WRITTEN.search(_strip_names(text))]


@pytest.mark.parametrize("module", MODULES)
def test_no_number_in_the_report_is_written_by_hand(module: str) -> None:
    assert _hand_written(module) == []


def test_the_check_finds_a_number_typed_into_a_figure_text() -> None:
    """The check itself: a FigureText with "1.33 mm" in its words is caught, through a variable
    and a helper function too; one whose numbers come from fields is not."""
    source = '''
def helper():
    return "predicts about 1.06 mm"


def fig(run, out):
    note = f"peak {run.peak:.3f} mm"
    return FigureText("k", "t", "p.png", "the paper: 1.33 mm", note + helper(), "(11) holds, γ ≤ 1")
'''
    tree = ast.parse(source)
    texts = _Texts(tree)
    texts.visit(tree)
    flagged = [text for _, text in texts.found if HAND_WRITTEN.search(_strip_names(text))]
    assert sorted(flagged) == ["predicts about 1.06 mm", "the paper: 1.33 mm"]
