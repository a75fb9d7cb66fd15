"""The names of the figures ``slipstack reproduce`` draws and the runs each is drawn from.

Plain data, no drawing imports: ``slipstack reproduce --help`` lists these keys without
loading matplotlib. :mod:`slipstack.analysis.catalogue` maps each key to its drawing
function (the function of that name in :mod:`slipstack.analysis.figures` or
:mod:`slipstack.analysis.beyond`).
"""

from __future__ import annotations

__all__ = ["FIGURE_KEYS", "figure_runs"]

FIGURE_KEYS = ("fig4a", "fig4b", "fig5a", "fig5b", "fig10", "fig11", "fig12", "fig13", "fig14", "cor_median", "fig15",
               "increment", "pareto", "grip_economy", "limit_errors")
"""Every figure, in the report's order: the paper's, then those beyond the paper."""

_RUNS = {"fig5a": (), "fig5b": (), "limit_errors": (), "increment": ("fig15", "fig15_per_taxel", "fig15_ft13"),
         "pareto": ("fig14", "fig15_open"),
         "grip_economy": ("fig15", "fig15_per_taxel", "fig15_ft13", "fig15_exact_law")}


def figure_runs(key: str) -> tuple[str, ...]:
    """The experiments (``analysis/runs.py`` keys) a figure is drawn from, in argument order
    (a figure without an entry is drawn from the experiment of its own name)."""
    return _RUNS.get(key, (key,))
