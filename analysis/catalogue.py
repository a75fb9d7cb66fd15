"""Every figure ``slipstack reproduce`` draws, in the report's order, and the runs it is drawn from.

The paper's figures (:mod:`slipstack.analysis.figures`), then those beyond the paper
(:mod:`slipstack.analysis.beyond`). Each entry is ``function(*runs, out_dir) -> FigureText``;
its runs are :func:`figure_runs` (keys of :data:`slipstack.analysis.runs.EXPERIMENTS`).
"""

from __future__ import annotations

from slipstack.analysis import beyond, figures

__all__ = ["FIGURES", "figure_runs"]

FIGURES = {"fig4a": figures.fig4a, "fig4b": figures.fig4b, "fig5a": figures.fig5a, "fig5b": figures.fig5b,
           "fig10": figures.fig10, "fig11": figures.fig11, "fig12": figures.fig12, "fig13": figures.fig13,
           "fig14": figures.fig14, "cor_median": figures.cor_median, "fig15": figures.fig15,
           "increment": figures.increment, "pareto": beyond.pareto, "grip_economy": beyond.grip_economy,
           "limit_errors": beyond.limit_errors}
"""Figure key → function(*runs, out_dir), in the report's order; the runs are :func:`figure_runs`."""

_RUNS = {"fig5a": (), "fig5b": (), "limit_errors": (), "increment": ("fig15", "fig15_per_taxel", "fig15_ft13"),
         "pareto": ("fig14", "fig15_open"),
         "grip_economy": ("fig15", "fig15_per_taxel", "fig15_ft13", "fig15_exact_law")}


def figure_runs(key: str) -> tuple[str, ...]:
    """The experiments (``analysis/runs.py`` keys) a figure is drawn from, in argument order."""
    return _RUNS.get(key, (key,))
