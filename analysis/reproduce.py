"""``slipstack reproduce``: the paper's §V experiments, figure by figure.

More in docs/modules.md, `analysis/reproduce.py`.
"""

from __future__ import annotations

import argparse
import html
import json
import multiprocessing
import os
import queue
import sys
import time
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from pathlib import Path
from typing import Any, Callable

from slipstack.analysis.figure_keys import FIGURE_KEYS, figure_runs, parse_variant
from slipstack.lib.output_file import writable_folder

__all__ = ["add_parser", "main_reproduce", "reproduce"]

QUICK_DURATION_S = 3.0

DIGESTS_FILE = "digests.json"  # experiment → SHA-256 of every payload it published: equal across runs
IDENTIFICATION = ("fig4a", "fig4b")  # the ramps the friction of the control experiments comes from
USES_IDENTIFIED_FRICTION = ("fig10", "fig10b", "fig11", "fig12")

Progress = Callable[[str, float], None]
_progress_queue: Any = None
"""In a worker process: where its runs report their progress (set by :func:`_start_worker`)."""


def _start_worker(progress_queue: Any) -> None:
    global _progress_queue
    _progress_queue = progress_queue


def _run_job(exp, duration: float | None, record: Path | None, prepare: tuple[str, ...]) -> Any:
    """One experiment (in a worker or in this process) and the costly work of the figures
    ``prepare`` on it: its :class:`~slipstack.analysis.runs.Run`, or for a sensitivity variant
    only what the sensitivity keeps of it."""
    from slipstack.analysis.catalogue import PREPARE
    from slipstack.analysis.runs import run_experiment

    def step(fraction: float) -> None:
        if _progress_queue is not None:
            _progress_queue.put((exp.key, fraction))

    run = run_experiment(exp, duration_s=duration, progress=step, record=record)
    for function in dict.fromkeys(PREPARE[key] for key in prepare):
        function(run)
    return run if parse_variant(exp.key) is None else run.replays["sensitivity"]


def default_jobs() -> int:
    """Worker processes: one per core this process may run on."""
    return len(os.sched_getaffinity(0))


def reproduce(out_dir: Path, *, quick: bool = False, only: list[str] | None = None,
              progress: Progress | None = None, jobs: int | None = None) -> list:
    """Run the experiments, draw the figures into ``out_dir``; returns the FigureTexts.

    The experiments run in ``jobs`` worker processes (default: one per core; 1: in this
    process); each is deterministic, so the results do not depend on how many. Figs. 10–12
    run with the μ and β ``slipstack identify`` finds on the Fig. 4 runs
    (:mod:`slipstack.analysis.friction`), which therefore run first whenever one of them is
    asked for; their recordings and the material file stay in ``out_dir``.
    """
    from slipstack.analysis import catalogue
    from slipstack.analysis.friction import identify_friction, with_friction
    from slipstack.analysis.runs import experiment

    writable_folder(out_dir, "--out")
    keys = [k for k in catalogue.FIGURES if not only or k in only]
    runs_needed = list(dict.fromkeys(k for key in keys for k in figure_runs(key, quick)))
    if any(k in USES_IDENTIFIED_FRICTION for k in runs_needed):
        runs_needed = [*IDENTIFICATION, *[k for k in runs_needed if k not in IDENTIFICATION]]
    duration = QUICK_DURATION_S if quick else None
    waiting = [k for k in runs_needed if k in USES_IDENTIFIED_FRICTION]
    ready = [k for k in runs_needed if k not in USES_IDENTIFIED_FRICTION]
    done: dict[str, float] = dict.fromkeys(runs_needed, 0.0)
    results: dict[str, Any] = {}
    friction = None

    def report(label: str) -> None:
        if progress:
            progress(label, sum(done.values()) / len(done))

    def job(key: str):
        exp = experiment(key)
        if key in USES_IDENTIFIED_FRICTION:
            exp = with_friction(exp, friction)
        prepare = tuple(f for f in keys if f in catalogue.PREPARE and key in figure_runs(f, quick))
        return exp, duration, out_dir / f"{key}.mcap" if key in IDENTIFICATION else None, prepare

    workers = max(1, min(jobs or default_jobs(), len(runs_needed)))
    if workers == 1:
        global _progress_queue
        local: queue.SimpleQueue = queue.SimpleQueue()
        _progress_queue = local
        try:
            for key in ready + waiting:
                if key in USES_IDENTIFIED_FRICTION and friction is None:
                    friction = identify_friction([out_dir / f"{k}.mcap" for k in IDENTIFICATION], out_dir)
                results[key] = _run_job(*job(key))
                done[key] = 1.0
                report(key)
        finally:
            _progress_queue = None
    else:
        context = multiprocessing.get_context("spawn")
        progress_queue = context.Queue()
        with ProcessPoolExecutor(workers, mp_context=context, initializer=_start_worker,
                                 initargs=(progress_queue,)) as pool:
            pending: dict[Future, str] = {pool.submit(_run_job, *job(k)): k for k in ready}
            try:
                while pending:
                    finished, _ = wait(pending, timeout=0.5, return_when=FIRST_COMPLETED)
                    while True:
                        try:
                            key, fraction = progress_queue.get_nowait()
                        except queue.Empty:
                            break
                        done[key] = max(done[key], min(fraction, 0.99))
                    for future in finished:
                        key = pending.pop(future)
                        results[key] = future.result()
                        done[key] = 1.0
                    if waiting and all(k in results for k in IDENTIFICATION if k in runs_needed):
                        friction = identify_friction([out_dir / f"{k}.mcap" for k in IDENTIFICATION], out_dir)
                        pending.update({pool.submit(_run_job, *job(k)): k for k in waiting})
                        waiting = []
                    running = [k for k in pending.values() if 0.0 < done[k] < 1.0]
                    report(", ".join(running[:3]) if running else "")
            except BaseException:  # Ctrl-C (the workers get it too) or a failed run: start nothing more
                pool.shutdown(wait=False, cancel_futures=True)
                raise
    if progress:
        progress("figures", 1.0)
    texts = [catalogue.FIGURES[key](*[results[k] for k in figure_runs(key, quick)], out_dir) for key in keys]
    if friction is not None:
        (out_dir / "identification.txt").write_text("\n".join(friction.log) + "\n")
    digests = {key: run.digest for key, run in results.items() if hasattr(run, "digest")}
    (out_dir / DIGESTS_FILE).write_text(json.dumps(digests, indent=1) + "\n")
    (out_dir / "index.html").write_text(_html(texts, quick))
    (out_dir / "report.md").write_text(_markdown(texts, quick))
    return texts


def _html_table(table: str) -> str:
    """A Markdown table (header, rule, rows) as an HTML table."""
    rows = [[html.escape(c.strip()) for c in line.strip().strip("|").split("|")] for line in table.splitlines()]
    head, body = rows[0], rows[2:]
    return ("<table><tr>" + "".join(f"<th>{c}</th>" for c in head) + "</tr>"
            + "".join("<tr>" + "".join(f"<td>{c}</td>" for c in r) + "</tr>" for r in body) + "</table>")


def _html(texts: list, quick: bool) -> str:
    note = (f"<p><b>Quick run</b>: every scene cut to {QUICK_DURATION_S:g} s; the numbers are not the paper's.</p>"
            if quick else "")
    parts = [
        "<!doctype html><html><head><meta charset='utf-8'><title>slipstack: the paper reproduced</title>",
        "<style>body{font-family:sans-serif;max-width:1200px;margin:auto;padding:1em}"
        "section{border-top:1px solid #ccc;padding:1em 0}img{max-width:100%}dt{font-weight:bold}"
        "table{border-collapse:collapse;font-size:85%;margin:0.5em 0}td,th{border:1px solid #ccc;padding:2px 6px}"
        "</style>",
        "</head><body><h1>Melchiorri 2000, §V, reproduced by slipstack</h1>", note,
    ]
    for t in texts:
        parts.append(f"<section id='{t.key}'><h2>{html.escape(t.title)}</h2>"
                     f"<img src='{html.escape(t.png)}' alt='{html.escape(t.title)}'><dl>"
                     f"<dt>The paper</dt><dd>{html.escape(t.paper)}</dd>"
                     f"<dt>slipstack</dt><dd>{html.escape(t.ours)}</dd>"
                     f"<dt>Where they differ, and why</dt><dd>{html.escape(t.differences)}</dd></dl>"
                     + "".join(_html_table(table) for table in t.table.split("\n\n") if table)
                     + "</section>")
    parts.append("</body></html>")
    return "\n".join(parts)


def _markdown(texts: list, quick: bool) -> str:
    lines = ["# Melchiorri 2000, §V, reproduced by slipstack", ""]
    if quick:
        lines += [f"*Quick run: every scene cut to {QUICK_DURATION_S:g} s; the numbers are not the paper's.*", ""]
    for t in texts:
        lines += [f"## {t.title}", "", f"![{t.title}]({t.png})", "", f"- **The paper**: {t.paper}",
                  f"- **slipstack**: {t.ours}", f"- **Where they differ, and why**: {t.differences}", ""]
        if t.table:
            lines += [t.table, ""]
    return "\n".join(lines)


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "reproduce", help="run the paper's experiments in lock-step and draw its figures",
        description="Run the paper's §V experiments in lock-step (deterministic: the same output every time) and "
                    "draw each of its figures as a PNG, with index.html and report.md beside them: what the paper "
                    "shows, what slipstack shows and where they differ and why. Also written: digests.json (the "
                    "SHA-256 of every payload per experiment), the Fig. 4 recordings and the material file "
                    "identified from them. Needs matplotlib (pip install 'slipstack[report]').")
    p.add_argument("--out", default="reproduce", help="output folder (default ./reproduce)")
    p.add_argument("--quick", action="store_true",
                   help=f"cut every scene to {QUICK_DURATION_S:g} s (CI: everything runs and draws, not the "
                        "paper's numbers)")
    p.add_argument("--only", nargs="+", metavar="FIG", choices=FIGURE_KEYS,
                   help=f"only these figures: {' '.join(FIGURE_KEYS)}")
    p.add_argument("--jobs", type=int, metavar="N", default=0,
                   help="experiments run at once, each in its own process (default 0: one per core; 1: all in "
                        "this process); the results do not depend on it")
    p.set_defaults(func=main_reproduce)


def main_reproduce(args: argparse.Namespace) -> int:
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        print("slipstack reproduce needs matplotlib: pip install 'slipstack[report]'", file=sys.stderr)
        return 2
    t0 = time.monotonic()

    tty = sys.stderr.isatty()
    shown = [-1]

    def progress(running: str, fraction: float) -> None:
        step = int(fraction * (200 if tty else 10))  # a redrawn bar on a terminal, ten lines in a log
        if step == shown[0]:
            return
        shown[0] = step
        bar = "#" * int(fraction * 30)
        start, end = ("\r", "") if tty else ("", "\n")
        print(f"{start}[{bar:<30}] {fraction * 100:5.1f} %  {time.monotonic() - t0:4.0f} s  {running:<40.40}",
              end=end, file=sys.stderr, flush=True)

    if args.jobs < 0:
        print(f"slipstack reproduce: --jobs must be 0 (one per core) or more, got {args.jobs}", file=sys.stderr)
        return 2
    out = Path(args.out)
    writable_folder(out, "--out")  # before minutes of runs
    texts = reproduce(out, quick=args.quick, only=args.only, progress=progress, jobs=args.jobs or None)
    figures = f"{len(texts)} figure{'s' if len(texts) != 1 else ''}"
    print(f"\nwrote {figures}, {out / 'index.html'} and {out / 'report.md'} in {time.monotonic() - t0:.0f} s",
          file=sys.stderr)
    return 0
