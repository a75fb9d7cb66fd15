"""Mutation testing of slipstack's numerical core and control-path nodes: plant one small
bug at a time, run the tests that should notice, report the bugs nobody noticed (the
*survivors*). Figures and commands: ``tests/mutation/README.md``.

Usage (from the worktree root; ``make mutation`` runs every configured module)::

More in docs/modules.md, `tests/mutation/mutate.py`.
"""

from __future__ import annotations

import argparse
import ast
import bisect
import gc
import importlib
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import tokenize
import tomllib
from dataclasses import asdict, dataclass, replace
from io import StringIO
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
CONFIG = HERE / "config.toml"
EQUIVALENT = HERE / "equivalent.txt"
KERNEL_PACKAGE = "lib/"
"""Where the numba kernels live: a module-level mutant elsewhere (``nodes/``) is frozen into
no kernel, so it shares the run's numba cache instead of recompiling every kernel."""
_SKIP = shutil.ignore_patterns(".venv", ".git", "__pycache__", "runs", "*.egg-info", "mutants")
"""Not copied into the mutation sandbox."""

_CMP_FLIP = {
    ast.Lt: ast.LtE, ast.LtE: ast.Lt, ast.Gt: ast.GtE, ast.GtE: ast.Gt,
    ast.Eq: ast.NotEq, ast.NotEq: ast.Eq, ast.Is: ast.IsNot, ast.IsNot: ast.Is,
    ast.In: ast.NotIn, ast.NotIn: ast.In,
}
_BIN_SWAP = {
    ast.Add: ast.Sub, ast.Sub: ast.Add, ast.Mult: ast.Div, ast.Div: ast.Mult,
    ast.Pow: ast.Mult, ast.FloorDiv: ast.Div, ast.BitAnd: ast.BitOr, ast.BitOr: ast.BitAnd,
}
_SYMBOL = {
    ast.Lt: "<", ast.LtE: "<=", ast.Gt: ">", ast.GtE: ">=", ast.Eq: "==", ast.NotEq: "!=",
    ast.Is: "is", ast.IsNot: "is not", ast.In: "in", ast.NotIn: "not in", ast.Add: "+",
    ast.Sub: "-", ast.Mult: "*", ast.Div: "/", ast.Pow: "**", ast.FloorDiv: "//",
    ast.BitAnd: "&", ast.BitOr: "|", ast.And: "and", ast.Or: "or",
}
OPERATORS = {
    "cmp": "comparison boundary or sense flipped (< <=, > >=, == !=, is / is not, in / not in)",
    "binop": "arithmetic swapped (+ -, * /, ** *, // /, & |), also in augmented assignments",
    "bool": "and / or swapped",
    "not": "`not` removed",
    "neg": "unary minus removed from a non-constant",
    "const": "number n -> n + 1; True / False swapped",
    "abs": "abs(x) -> x",
    "minmax": "min / max swapped",
    "return": "a returned value replaced by None (plain Python functions only)",
    "guard": "a guard removed: the condition of an `if` whose body ends in return, continue or break -> False",
}


@dataclass(frozen=True)
class Mutant:
    """One planted bug: where (1-based line, 0-based column of the changed text), which
    operator, the original and mutated text of the changed expression or statement, and
    what names it independently of its line (``scope``, ``context``: see :attr:`key`)."""

    path: str
    line: int
    col: int
    operator: str
    original: str
    mutated: str
    end_line: int
    end_col: int
    in_kernel: bool
    at_module_level: bool
    scope: str = "<module>"
    context: str = ""
    occurrence: int = 0

    @property
    def key(self) -> str:
        """Content name used in ``equivalent.txt``: ``path scope operator: context -> mutated``,
        the context being the changed text in «» with its neighbouring tokens and the start of
        its line, whitespace collapsed and comments left out; `` [k]`` marks the k-th further
        mutant with the same name in the same function (a line repeated there)."""
        name = f"{self.path} {self.scope} {self.operator}: {self.context} -> {_collapse(self.mutated)}"
        return name + (f" [{self.occurrence}]" if self.occurrence else "")

    def describe(self) -> str:
        return f"line {self.line}: {self.key}"


NEIGHBOURS = 4
"""Tokens of the mutant's own logical line kept on each side of it in its key."""
LEAD = 3
"""Tokens of the start of the mutant's logical line kept in its key (what the line assigns or returns)."""


def _collapse(text: str) -> str:
    return " ".join(text.split())


class _Tokens:
    """The module's tokens (comments, indents and line breaks left out), to name a mutant
    by its neighbours: see :attr:`Mutant.key`."""

    def __init__(self, source: str) -> None:
        self.source = source
        starts = [0]
        for line in source.splitlines(keepends=True):
            starts.append(starts[-1] + len(line))
        self._offsets = starts
        self.spans: list[tuple[int, int, int]] = []  # (start, end, logical line) in characters
        self.comments: list[tuple[int, int]] = []
        logical = 0
        for tok in tokenize.generate_tokens(StringIO(source).readline):
            start, end = self.offset(*tok.start), self.offset(*tok.end)
            if tok.type == tokenize.COMMENT:
                self.comments.append((start, end))
            elif tok.type == tokenize.NEWLINE:
                logical += 1
            elif tok.type not in (tokenize.NL, tokenize.INDENT, tokenize.DEDENT, tokenize.ENDMARKER):
                self.spans.append((start, end, logical))
        self._starts = [span[0] for span in self.spans]

    def offset(self, line: int, col: int) -> int:
        """Character offset of a tokenize position (1-based line, 0-based character column)."""
        return self._offsets[line - 1] + col

    def text(self, start: int, end: int) -> str:
        """``source[start:end]`` without its comments, whitespace collapsed."""
        parts, at = [], start
        for c_start, c_end in self.comments:
            if start <= c_start < end:
                parts.append(self.source[at:c_start])
                at = c_end
        parts.append(self.source[at:end])
        return _collapse("".join(parts))

    def context(self, start: int, end: int) -> str:
        """The text ``start:end`` in «», with up to :data:`NEIGHBOURS` tokens of its logical line
        each side, and the line's first :data:`LEAD` tokens (``… `` marks the tokens left out)."""
        first = bisect.bisect_left(self._starts, start)
        last = bisect.bisect_right(self._starts, end - 1) - 1
        logical = self.spans[first][2]
        head = first
        while head > 0 and self.spans[head - 1][2] == logical:
            head -= 1
        before = max(head, first - NEIGHBOURS)
        if before - head <= LEAD:
            before = head
        after = last
        while after + 1 < len(self.spans) and after - last < NEIGHBOURS and self.spans[after + 1][2] == logical:
            after += 1
        left = self.text(self.spans[before][0], start) if before < first else ""
        if before > head:
            left = f"{self.text(self.spans[head][0], self.spans[head + LEAD - 1][1])} … {left}"
        right = self.text(end, self.spans[after][1]) if after > last else ""
        gap_left = " " if left and self.source[start - 1].isspace() else ""
        gap_right = " " if right and self.source[end].isspace() else ""
        return f"{left}{gap_left}«{self.text(start, end)}»{gap_right}{right}"


def _is_docstring(node: ast.AST) -> bool:
    return (
        isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant) and isinstance(node.value.value, str)
    )


def _is_njit(decorator: ast.expr) -> bool:
    target = decorator.func if isinstance(decorator, ast.Call) else decorator
    return isinstance(target, ast.Name) and target.id in ("njit", "jit")


class _Collector(ast.NodeVisitor):
    """Walks a module and records every mutation site (see :data:`OPERATORS`)."""

    def __init__(self, path: str, source: str) -> None:
        self.path = path
        self.source = source
        self.tokens = _Tokens(source)
        self.mutants: list[Mutant] = []
        self._func_stack: list[bool] = []  # per enclosing function: is it a numba kernel?
        self._names: list[str] = []  # enclosing classes and functions

    # --- where not to mutate ------------------------------------------------------------
    def visit_FunctionDef(self, node: ast.FunctionDef) -> None:
        self._func_stack.append(any(_is_njit(d) for d in node.decorator_list))
        for default in node.args.defaults + [d for d in node.args.kw_defaults if d is not None]:
            self.visit(default)
        self._names.append(node.name)
        for stmt in node.body:
            if not _is_docstring(stmt):
                self.visit(stmt)
        self._names.pop()
        self._func_stack.pop()

    visit_AsyncFunctionDef = visit_FunctionDef  # type: ignore[assignment]

    def visit_ClassDef(self, node: ast.ClassDef) -> None:
        self._names.append(node.name)
        for stmt in node.body:
            if not _is_docstring(stmt):
                self.visit(stmt)
        self._names.pop()

    def visit_Module(self, node: ast.Module) -> None:
        for stmt in node.body:
            if _is_docstring(stmt) or isinstance(stmt, (ast.Import, ast.ImportFrom)):
                continue
            if isinstance(stmt, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "__all__" for t in stmt.targets):
                continue
            if isinstance(stmt, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "JIT" for t in stmt.targets):
                continue  # numba options, not behaviour
            self.visit(stmt)

    def visit_AnnAssign(self, node: ast.AnnAssign) -> None:
        if node.value is not None:
            self.visit(node.value)

    def visit_Raise(self, node: ast.Raise) -> None:
        return  # error messages: their wording is tested where it matters, not mutated

    def visit_JoinedStr(self, node: ast.JoinedStr) -> None:
        return

    # --- mutation sites -------------------------------------------------------------------
    def _add(self, node: ast.AST, operator: str, replacement: ast.AST, *, statement: bool = False) -> None:
        original = ast.get_source_segment(self.source, node)
        if original is None:
            return
        text = ast.unparse(replacement)
        mutated = text if statement else f"({text})"
        in_kernel = bool(self._func_stack) and self._func_stack[-1]
        line_bytes = self.source.splitlines(keepends=True)
        start = self.tokens.offset(node.lineno, len(line_bytes[node.lineno - 1].encode()[:node.col_offset].decode()))
        end = self.tokens.offset(node.end_lineno,
                                 len(line_bytes[node.end_lineno - 1].encode()[:node.end_col_offset].decode()))
        self.mutants.append(Mutant(self.path, node.lineno, node.col_offset, operator, original, mutated,
                                   node.end_lineno, node.end_col_offset, in_kernel, not self._func_stack,
                                   ".".join(self._names) or "<module>", self.tokens.context(start, end)))

    def visit_Compare(self, node: ast.Compare) -> None:
        for k, op in enumerate(node.ops):
            flip = _CMP_FLIP.get(type(op))
            if flip is not None:
                ops = list(node.ops)
                ops[k] = flip()
                self._add(node, "cmp", ast.Compare(node.left, ops, node.comparators))
        self.generic_visit(node)

    def visit_BinOp(self, node: ast.BinOp) -> None:
        swap = _BIN_SWAP.get(type(node.op))
        if swap is not None:
            self._add(node, "binop", ast.BinOp(node.left, swap(), node.right))
        self.generic_visit(node)

    def visit_AugAssign(self, node: ast.AugAssign) -> None:
        swap = _BIN_SWAP.get(type(node.op))
        if swap is not None:
            self._add(node, "binop", ast.AugAssign(node.target, swap(), node.value), statement=True)
        self.generic_visit(node)

    def visit_BoolOp(self, node: ast.BoolOp) -> None:
        other = ast.Or() if isinstance(node.op, ast.And) else ast.And()
        self._add(node, "bool", ast.BoolOp(other, node.values))
        self.generic_visit(node)

    def visit_UnaryOp(self, node: ast.UnaryOp) -> None:
        if isinstance(node.op, ast.Not):
            self._add(node, "not", node.operand)
        elif isinstance(node.op, ast.USub):
            if isinstance(node.operand, ast.Constant):
                value = node.operand.value
                if isinstance(value, (int, float)) and not isinstance(value, bool):
                    self._add(node, "const", ast.Constant(-value + 1))
                return
            self._add(node, "neg", node.operand)
        self.generic_visit(node)

    def visit_Constant(self, node: ast.Constant) -> None:
        value = node.value
        if isinstance(value, bool):
            self._add(node, "const", ast.Constant(not value))
        elif isinstance(value, (int, float)):
            self._add(node, "const", ast.Constant(value + 1))

    def visit_Call(self, node: ast.Call) -> None:
        name = node.func.id if isinstance(node.func, ast.Name) else None
        if name == "abs" and len(node.args) == 1 and not node.keywords:
            self._add(node, "abs", node.args[0])
        if name in ("min", "max"):
            other = "max" if name == "min" else "min"
            self._add(node, "minmax", ast.Call(ast.Name(other, ast.Load()), node.args, node.keywords))
        self.generic_visit(node)

    def visit_If(self, node: ast.If) -> None:
        if isinstance(node.body[-1], (ast.Return, ast.Continue, ast.Break)):
            self._add(node.test, "guard", ast.Constant(False))
        self.generic_visit(node)

    def visit_Return(self, node: ast.Return) -> None:
        in_kernel = bool(self._func_stack) and self._func_stack[-1]
        if node.value is not None and not in_kernel and not (
            isinstance(node.value, ast.Constant) and node.value.value is None
        ):
            self._add(node, "return", ast.Return(ast.Constant(None)), statement=True)
        self.generic_visit(node)


def collect_mutants(path: str, source: str) -> list[Mutant]:
    """Every mutant of one module's source, in source order."""
    collector = _Collector(path, source)
    collector.visit(ast.parse(source))
    mutants, seen = [], {}
    for m in sorted(collector.mutants, key=lambda m: (m.line, m.col, m.operator, m.mutated)):
        seen[m.key] = seen.get(m.key, -1) + 1
        mutants.append(replace(m, occurrence=seen[m.key]))
    return mutants


def apply(source: str, mutant: Mutant) -> str:
    """The source with the mutant's text in place of the original segment."""
    lines = source.splitlines(keepends=True)
    offsets = [0]
    for line in lines:
        offsets.append(offsets[-1] + len(line.encode()))
    raw = source.encode()
    start = offsets[mutant.line - 1] + mutant.col
    end = offsets[mutant.end_line - 1] + mutant.end_col
    return (raw[:start] + mutant.mutated.encode() + raw[end:]).decode()


# --- running ----------------------------------------------------------------------------


@dataclass
class Outcome:
    mutant: Mutant
    status: str  # killed, timeout, survived, equivalent, error
    seconds: float
    detail: str = ""


REASON = "  # "
"""Between an entry's key and its reason in ``equivalent.txt`` (a key never holds two spaces)."""


def load_equivalent(path: Path = EQUIVALENT) -> dict[str, str]:
    """``equivalent.txt`` as ``{key: reason}``; every entry must carry a reason."""
    entries: dict[str, str] = {}
    if not path.exists():
        return entries
    for number, raw in enumerate(path.read_text().splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        key, sep, reason = line.partition(REASON)
        if not sep or not reason.strip():
            raise SystemExit(f"{path}:{number}: an equivalent mutant needs '{REASON}reason' after its key")
        if _collapse(key) in entries:
            raise SystemExit(f"{path}:{number}: listed twice: {key}")
        entries[_collapse(key)] = reason.strip()
    return entries


def stale_entries(equivalent: dict[str, str], mutants: dict[str, list[Mutant]]) -> list[str]:
    """The entries of ``equivalent`` for the modules of ``mutants`` (path -> every mutant of it)
    that name no mutant of today's code."""
    keys = {m.key for ms in mutants.values() for m in ms}
    return [k for k in equivalent if k.split(" ", 1)[0] in mutants and k not in keys]


class _Sandbox:
    """A private copy of the worktree that the tests import as ``slipstack``.

    The source folders are copied to ``<dir>/tree`` and ``<dir>/pkgroot/slipstack/<pkg>``
    links to them; ``pkgroot`` goes first on PYTHONPATH, so the import system finds the
    copy before the editable install's finder (which maps to the worktree). The worktree
    itself is never written: one can keep editing and testing while a run goes on.
    """

    PACKAGES = ("lib", "messages", "nodes", "launch")

    def __init__(self, workdir: Path) -> None:
        self.tree = workdir / "tree"
        shutil.copytree(ROOT, self.tree, ignore=_SKIP, symlinks=True)
        self.pkgroot = workdir / "pkgroot"
        (self.pkgroot / "slipstack").mkdir(parents=True)
        for name in self.PACKAGES:
            (self.pkgroot / "slipstack" / name).symlink_to(self.tree / name)

    def check_imports(self, env: dict[str, str], module: str) -> None:
        """Fails loudly unless ``module`` is imported from the copy (not from the worktree)."""
        name = "slipstack." + module.removesuffix(".py").replace("/", ".")
        out = subprocess.run([sys.executable, "-c", f"import {name} as m; print(m.__file__)"], cwd=self.tree,
                             env=env, capture_output=True, text=True, check=True).stdout.strip()
        if not out.startswith(str(self.pkgroot)):
            raise SystemExit(f"{name} was imported from {out}, not from the mutation copy {self.pkgroot}")


_PRELOADED = ("numpy", "scipy.optimize", "numba", "pytest", "hypothesis", "msgpack")
"""Imported once by the runner; every forked test process starts with them."""


def _preload() -> None:
    """Import the heavy third-party modules once, here, so that each forked test process
    starts with them (about 2 s of CPU per mutant). slipstack itself is never imported
    by the runner: each child imports it, mutant included, from the copy.

    Two more savings per child (measured: 0.50 -> 0.19 s of CPU for a small test file):
    a throw-away kernel compiled here, uncached, loads numba's lowering registries once
    (each child would load them on its first kernel); ``gc.freeze`` keeps the runner's
    objects out of the children's collections (pytest collects at its end)."""
    for name in _PRELOADED:
        importlib.import_module(name)
    import numba
    import numpy as np

    numba.njit(cache=False)(lambda a: a.sum() + np.sqrt(a[0]))(np.ones(2))
    gc.collect()
    gc.freeze()


def _child(tests: list[str], env: dict[str, str], cwd: Path, out_path: Path) -> None:
    """Runs in the forked process: the mutant's environment, then ``pytest -x`` on ``tests``."""
    code = 4
    try:
        os.setsid()
        fd = os.open(out_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        os.dup2(fd, 1)
        os.dup2(fd, 2)
        os.chdir(cwd)
        os.environ.clear()
        os.environ.update(env)
        sys.dont_write_bytecode = True
        sys.path[:0] = [p for p in env["PYTHONPATH"].split(os.pathsep) if p]
        importlib.invalidate_caches()
        from numba.core import config as numba_config

        numba_config.reload_config()  # NUMBA_CACHE_DIR, NUMBA_DISABLE_JIT of this mutant
        import pytest

        code = int(pytest.main(["-x", "-q", "-p", "no:cacheprovider", "--no-header", *tests]))
    except BaseException as exc:  # noqa: BLE001 - report anything, never return into the runner
        print(f"mutation child failed: {exc!r}", flush=True)
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)


def _pytest(tests: list[str], env: dict[str, str], timeout_s: float, cwd: Path) -> tuple[str, float, str]:
    """Runs ``tests`` in a forked process; ``(status, seconds, detail)``."""
    out_path = cwd.parent / "pytest-output.txt"
    sys.stdout.flush()
    sys.stderr.flush()
    started = time.monotonic()
    pid = os.fork()
    if pid == 0:
        _child(tests, env, cwd, out_path)
    while True:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            break
        if time.monotonic() - started > timeout_s:
            os.killpg(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
            return "timeout", time.monotonic() - started, ""
        time.sleep(0.02)
    elapsed = time.monotonic() - started
    code = os.waitstatus_to_exitcode(status)
    out = out_path.read_text(errors="replace") if out_path.exists() else ""
    if code == 0:
        return "survived", elapsed, ""
    if code < 0:
        return "killed", elapsed, f"the test process died by signal {-code}"
    if code in (1, 2, 3, 4):  # tests failed, interrupted (collection error), internal error, conftest crashed
        failed = [ln for ln in out.splitlines() if ln.startswith(("FAILED", "ERROR"))]
        errors = [ln for ln in out.splitlines() if ln.startswith("E ") and "Error" in ln]
        head = failed[0] if failed else out.strip().splitlines()[-1] if out.strip() else ""
        return "killed", elapsed, head + (f" ({errors[0][1:].strip()})" if errors else "")
    return "error", elapsed, f"pytest exit code {code}: {out[-500:]}"


def _env(sandbox: _Sandbox, cache_dir: Path, *, interpreted: bool = False) -> dict[str, str]:
    env = dict(os.environ)
    path = os.pathsep.join(p for p in (str(sandbox.pkgroot), env.get("PYTHONPATH", "")) if p)
    env.update(NUMBA_CACHE_DIR=str(cache_dir), PYTHONDONTWRITEBYTECODE="1", PYTHONPATH=path)
    env.pop("NUMBA_DISABLE_JIT", None)
    if interpreted:
        env["NUMBA_DISABLE_JIT"] = "1"
    return env


_PYTHON_ONLY_ERRORS = ("ZeroDivisionError", "math domain error", "OverflowError")
"""Exceptions interpreted kernels raise where compiled ones return inf or NaN (IEEE)."""


def _run_mutant(sandbox: _Sandbox, mutant: Mutant, tests: list[str], shared_cache: Path, timeout_s: float,
                interpreted: bool) -> tuple[str, float, str]:
    """One mutant's test run (the mutant is in place in the copy). Compiled, kernel and
    module-level mutants of :data:`KERNEL_PACKAGE` get an empty numba cache; with ``interpreted`` every mutant runs
    under NUMBA_DISABLE_JIT, and a kill by an exception only interpreted code raises is
    confirmed compiled."""
    if interpreted:
        status, seconds, detail = _pytest(tests, _env(sandbox, shared_cache, interpreted=True), timeout_s,
                                          sandbox.tree)
        if not (status == "killed" and any(e in detail for e in _PYTHON_ONLY_ERRORS)):
            return status, seconds, detail
    elif not (mutant.in_kernel or (mutant.at_module_level and mutant.path.startswith(KERNEL_PACKAGE))):
        return _pytest(tests, _env(sandbox, shared_cache), timeout_s, sandbox.tree)
    cache = Path(tempfile.mkdtemp(prefix="numba-", dir=sandbox.tree.parent))
    try:
        return _pytest(tests, _env(sandbox, cache), timeout_s, sandbox.tree)
    finally:
        shutil.rmtree(cache, ignore_errors=True)


def runs_interpreted(mutants: list[Mutant], asked: bool) -> bool:
    """Whether a module's mutants run under NUMBA_DISABLE_JIT: ``--interpreted`` applies to a
    module with numba kernels; one without has none to recompile, and interpreting the kernels
    its tests call only slows them (lib/rig/actuator.py: timeouts, counted as kills)."""
    return asked and any(m.in_kernel for m in mutants)


def run_module(sandbox: _Sandbox, path: str, tests: list[str], mutants: list[Mutant], equivalent: dict[str, str],
               log, *, interpreted: bool = False) -> tuple[list[Outcome], float]:
    """Runs every mutant of one module in the copy; returns the outcomes and the clean run's time (s)."""
    shared_cache = sandbox.tree.parent / "numba-shared"
    shared_cache.mkdir(exist_ok=True)
    sandbox.check_imports(_env(sandbox, shared_cache), path)
    status, clean_s, detail = _pytest(tests, _env(sandbox, shared_cache), 600.0, sandbox.tree)
    if status != "survived":
        raise SystemExit(f"{path}: its tests fail without any mutant ({status}: {detail}); fix them first")
    log(f"{path}: clean run {clean_s:.1f} s, {len(mutants)} mutants, tests: {' '.join(tests)}")
    timeout_s = max(60.0, 5.0 * clean_s)
    target = sandbox.tree / path
    original = target.read_text()
    outcomes: list[Outcome] = []
    try:
        for k, mutant in enumerate(mutants, start=1):
            target.write_text(apply(original, mutant))
            try:
                status, seconds, detail = _run_mutant(sandbox, mutant, tests, shared_cache, timeout_s, interpreted)
            finally:
                target.write_text(original)
            if status == "survived" and mutant.key in equivalent:
                status, detail = "equivalent", equivalent[mutant.key]
            outcomes.append(Outcome(mutant, status, seconds, detail))
            log(f"  [{k}/{len(mutants)}] {status:10s} {seconds:5.1f} s  {mutant.describe()}")
    finally:
        target.write_text(original)
    return outcomes, clean_s


def summarise(outcomes: list[Outcome]) -> dict[str, int | float]:
    """Counts per status and the share of non-equivalent mutants killed (timeouts count as killed)."""
    counts = {s: sum(o.status == s for o in outcomes) for s in ("killed", "timeout", "survived", "equivalent", "error")}
    relevant = len(outcomes) - counts["equivalent"]
    dead = counts["killed"] + counts["timeout"]
    return {"mutants": len(outcomes), **counts, "killed_pct": round(100.0 * dead / relevant, 1) if relevant else 100.0}


def report(results: dict[str, list[Outcome]], wall_s: float, stale: list[str], equivalent: dict[str, str]) -> str:
    """A Markdown report: the table per module, every survivor by line and key, the entries of
    ``equivalent.txt`` that are stale or whose mutant a test killed."""
    rows = ["| module | mutants | killed | timeout | survived | equivalent | error | % killed |",
            "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for path, outcomes in results.items():
        s = summarise(outcomes)
        rows.append(f"| {path} | {s['mutants']} | {s['killed']} | {s['timeout']} | {s['survived']} | "
                    f"{s['equivalent']} | {s['error']} | {s['killed_pct']} |")
    lines = ["# Mutation report", "", *rows, "", f"wall time {wall_s / 60:.1f} min", ""]
    survivors = [o for outcomes in results.values() for o in outcomes if o.status in ("survived", "error")]
    lines.append(f"## Survivors ({len(survivors)})")
    lines += [f"- {o.mutant.describe()} [{o.status}] {o.detail}".rstrip() for o in survivors] or ["none"]
    if stale:
        lines += ["", "## Stale entries of equivalent.txt: they name no mutant (re-derive or drop them)"]
        lines += [f"- {k}" for k in stale]
    wrong = [o for outcomes in results.values() for o in outcomes
             if o.mutant.key in equivalent and o.status in ("killed", "timeout")]
    if wrong:
        lines += ["", "## Entries of equivalent.txt whose mutant a test kills (drop them)"]
        lines += [f"- {o.mutant.describe()} ({o.detail})" for o in wrong]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    config = tomllib.loads(CONFIG.read_text())["module"]
    parser = argparse.ArgumentParser(
        description="Mutation testing: plants one bug at a time in a module and runs its tests "
                    f"(modules and test selections: {CONFIG.relative_to(ROOT)}). Takes long: not for CI.",
        epilog="operators: " + "; ".join(f"{k}: {v}" for k, v in OPERATORS.items()))
    parser.add_argument("modules", nargs="*", help=f"module paths (default: all of {', '.join(config)})")
    parser.add_argument("--line", type=int, action="append", help="only the mutants on this line (repeatable)")
    parser.add_argument("--operator", choices=sorted(OPERATORS), action="append", help="only these operators")
    parser.add_argument("--list", action="store_true", help="print the mutants (line and key) and run nothing")
    parser.add_argument("--check", action="store_true",
                        help="only check equivalent.txt against the modules' mutants of today: exit 1 on a stale entry")
    parser.add_argument("--interpreted", action="store_true",
                        help="run the mutants under NUMBA_DISABLE_JIT=1 (a mutated file's kernels would "
                             "otherwise be recompiled for every mutant: 1.5-3 s instead of 10-30 s per mutant "
                             "on 2 busy cores); a kill by ZeroDivisionError or a math domain error, which "
                             "compiled kernels do not raise, is re-checked compiled; a module without "
                             "kernels runs compiled")
    parser.add_argument("--sample", type=int, default=1, metavar="K",
                        help="only every K-th mutant of each module (in source order, starting with the first): "
                             "a fixed, repeatable subset for a machine too busy for the whole run")
    parser.add_argument("--rerun", type=Path, metavar="RESULTS_JSON",
                        help="only the mutants that survived (or erred) in an earlier results.json")
    parser.add_argument("--report", type=Path, default=Path(tempfile.gettempdir()) / f"slipstack-mutation-{os.getuid()}",
                        help="folder for report.md and results.json (default: %(default)s)")
    args = parser.parse_args(argv)
    modules = args.modules or list(config)
    unknown = [m for m in modules if m not in config]
    if unknown:
        parser.error(f"not configured: {', '.join(unknown)}; add a [module.\"PATH\"] table with its tests to {CONFIG}")
    equivalent = load_equivalent()
    unconfigured = [k for k in equivalent if k.split(" ", 1)[0] not in config]
    if unconfigured:
        raise SystemExit(f"{EQUIVALENT.name} names modules that {CONFIG.name} does not list: " + "; ".join(unconfigured))
    everything = {path: collect_mutants(path, (ROOT / path).read_text()) for path in modules}
    stale = stale_entries(equivalent, everything)
    for key in stale:
        print(f"stale entry of {EQUIVALENT.name} (it names no mutant; re-derive it from --list or drop it): {key}",
              file=sys.stderr)
    if args.check:
        listed = sum(k.split(" ", 1)[0] in everything for k in equivalent)
        print(f"{EQUIVALENT.name}: {listed - len(stale)} of {listed} entries for {len(modules)} modules name a mutant")
        return 1 if stale else 0
    selected: dict[str, list[Mutant]] = {}
    for path, mutants in everything.items():
        mutants = mutants[::args.sample]
        if args.line:
            mutants = [m for m in mutants if m.line in args.line]
        if args.operator:
            mutants = [m for m in mutants if m.operator in args.operator]
        selected[path] = mutants
    if args.rerun:
        earlier = json.loads(args.rerun.read_text())
        again = {Mutant(**{k: v for k, v in o.items() if k not in ("status", "seconds", "detail")}).key
                 for outs in earlier.values() for o in outs if o["status"] in ("survived", "error", "equivalent")}
        selected = {p: [m for m in ms if m.key in again] for p, ms in selected.items()}
    if args.list:
        for path, mutants in selected.items():
            for m in mutants:
                print(f"line {m.line}{' (kernel)' if m.in_kernel else ''}: {m.key}")
        print(f"{sum(map(len, selected.values()))} mutants")
        return 0
    args.report.mkdir(parents=True, exist_ok=True)
    started = time.monotonic()
    results: dict[str, list[Outcome]] = {}
    _preload()
    with tempfile.TemporaryDirectory(prefix="slipstack-mutation-") as tmp:
        sandbox = _Sandbox(Path(tmp))
        for path in modules:
            results[path], _ = run_module(sandbox, path, config[path]["tests"], selected[path], equivalent,
                                          lambda msg: print(msg, flush=True),
                                          interpreted=runs_interpreted(everything[path], args.interpreted))
    text = report(results, time.monotonic() - started, stale, equivalent)
    (args.report / "report.md").write_text(text)
    (args.report / "results.json").write_text(json.dumps(
        {p: [{**asdict(o.mutant), "status": o.status, "seconds": round(o.seconds, 2), "detail": o.detail}
             for o in outs] for p, outs in results.items()}, indent=1))
    print(text)
    print(f"report: {args.report / 'report.md'}")
    return 1 if any(o.status in ("survived", "error") for outs in results.values() for o in outs) else 0


if __name__ == "__main__":
    sys.exit(main())
