"""``slipstack reproduce``: the paper's §V experiments, figure by figure.

More in docs/modules.md, `analysis/reproduce.py`.
"""

from __future__ import annotations

import argparse
import html
import json
import sys
import time
from pathlib import Path

from slipstack.analysis.figure_keys import FIGURE_KEYS, figure_runs
from slipstack.lib.output_file import writable_folder

__all__ = ["add_parser", "main_reproduce", "reproduce"]

QUICK_DURATION_S = 3.0

DIGESTS_FILE = "digests.json"  # experiment → SHA-256 of every payload it published: equal across runs
IDENTIFICATION = ("fig4a", "fig4b")  # the ramps the friction of the control experiments comes from
USES_IDENTIFIED_FRICTION = ("fig10", "fig11", "fig12")


def reproduce(out_dir: Path, *, quick: bool = False, only: list[str] | None = None,
              progress=None) -> list:
    """Run the experiments, draw the figures into ``out_dir``; returns the FigureTexts.

    Figs. 10–12 run with the μ and β ``slipstack identify`` finds on the Fig. 4 runs
    (:mod:`slipstack.analysis.friction`), which therefore run first whenever one of
    them is asked for; their recordings and the material file stay in ``out_dir``.
    """
    from slipstack.analysis import catalogue
    from slipstack.analysis.friction import identify_friction, with_friction
    from slipstack.analysis.runs import EXPERIMENTS, run_experiment

    writable_folder(out_dir, "--out")
    keys = [k for k in catalogue.FIGURES if not only or k in only]
    runs_needed = list(dict.fromkeys(k for key in keys for k in figure_runs(key)))
    if any(k in USES_IDENTIFIED_FRICTION for k in runs_needed):
        runs_needed = [*IDENTIFICATION, *[k for k in runs_needed if k not in IDENTIFICATION]]
    duration = QUICK_DURATION_S if quick else None
    runs, friction = {}, None
    for n, key in enumerate(runs_needed):
        def step(fraction: float, key=key, n=n) -> None:
            if progress:
                progress(key, (n + fraction) / len(runs_needed))

        exp = EXPERIMENTS[key]
        if key in USES_IDENTIFIED_FRICTION:
            if friction is None:
                friction = identify_friction([out_dir / f"{k}.mcap" for k in IDENTIFICATION], out_dir)
            exp = with_friction(exp, friction)
        record = out_dir / f"{key}.mcap" if key in IDENTIFICATION else None
        runs[key] = run_experiment(exp, duration_s=duration, progress=step, record=record)
    if progress:
        progress("done", 1.0)
    texts = [catalogue.FIGURES[key](*[runs[k] for k in figure_runs(key)], out_dir) for key in keys]
    if friction is not None:
        (out_dir / "identification.txt").write_text("\n".join(friction.log) + "\n")
    digests = {key: run.digest for key, run in runs.items()}
    (out_dir / DIGESTS_FILE).write_text(json.dumps(digests, indent=1) + "\n")
    (out_dir / "index.html").write_text(_html(texts, quick))
    (out_dir / "report.md").write_text(_markdown(texts, quick))
    return texts


def _html(texts: list, quick: bool) -> str:
    note = "<p><b>Quick run</b>: every scene cut to 3 s; the numbers are not the paper's.</p>" if quick else ""
    parts = [
        "<!doctype html><html><head><meta charset='utf-8'><title>slipstack: the paper reproduced</title>",
        "<style>body{font-family:sans-serif;max-width:1200px;margin:auto;padding:1em}"
        "section{border-top:1px solid #ccc;padding:1em 0}img{max-width:100%}dt{font-weight:bold}</style>",
        "</head><body><h1>Melchiorri 2000, §V, reproduced by slipstack</h1>", note,
    ]
    for t in texts:
        parts.append(f"<section id='{t.key}'><h2>{html.escape(t.title)}</h2>"
                     f"<img src='{html.escape(t.png)}' alt='{html.escape(t.title)}'><dl>"
                     f"<dt>The paper</dt><dd>{html.escape(t.paper)}</dd>"
                     f"<dt>slipstack</dt><dd>{html.escape(t.ours)}</dd>"
                     f"<dt>Where they differ, and why</dt><dd>{html.escape(t.differences)}</dd></dl></section>")
    parts.append("</body></html>")
    return "\n".join(parts)


def _markdown(texts: list, quick: bool) -> str:
    lines = ["# Melchiorri 2000, §V, reproduced by slipstack", ""]
    if quick:
        lines += ["*Quick run: every scene cut to 3 s; the numbers are not the paper's.*", ""]
    for t in texts:
        lines += [f"## {t.title}", "", f"![{t.title}]({t.png})", "", f"- **The paper**: {t.paper}",
                  f"- **slipstack**: {t.ours}", f"- **Where they differ, and why**: {t.differences}", ""]
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

    def progress(key: str, fraction: float) -> None:
        step = int(fraction * (50 if tty else 10))  # a redrawn bar on a terminal, ten lines in a log
        if step == shown[0]:
            return
        shown[0] = step
        bar = "#" * int(fraction * 30)
        start, end = ("\r", "") if tty else ("", "\n")
        print(f"{start}[{bar:<30}] {fraction * 100:5.1f} %  {key:<6}", end=end, file=sys.stderr, flush=True)

    out = Path(args.out)
    writable_folder(out, "--out")  # before minutes of runs
    texts = reproduce(out, quick=args.quick, only=args.only, progress=progress)
    figures = f"{len(texts)} figure{'s' if len(texts) != 1 else ''}"
    print(f"\nwrote {figures}, {out / 'index.html'} and {out / 'report.md'} in {time.monotonic() - t0:.0f} s",
          file=sys.stderr)
    return 0
