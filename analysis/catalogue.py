"""Every figure ``slipstack reproduce`` draws, in the report's order, and its drawing function.

The keys and the runs each figure is drawn from are :mod:`slipstack.analysis.figure_keys`
(importable without matplotlib); a key names its function in one of the modules below
(the paper's figures, what its method does on measured data, and those beyond the
paper). Each function is ``function(*runs, out_dir) -> FigureText``.
"""

from __future__ import annotations

from collections.abc import Callable

from slipstack.analysis import beyond, figures, figures_control, figures_detection, measured, sensitivity
from slipstack.analysis.figure_keys import FIGURE_KEYS

__all__ = ["FIGURES", "PREPARE"]


def _drawing_function(key: str) -> Callable:
    for module in (measured, figures, figures_control, figures_detection, sensitivity, beyond):
        if callable(draw := getattr(module, key, None)):
            return draw
    raise LookupError(f"figure {key!r} of analysis/figure_keys.py has no function of that name in the modules "
                      "of analysis/catalogue.py: add one or remove the key")


FIGURES = {key: _drawing_function(key) for key in FIGURE_KEYS}
"""Figure key → function(*runs, out_dir), in the report's order; the runs are
:func:`slipstack.analysis.figure_keys.figure_runs`."""

PREPARE = {"measured": measured.prepare, "sensitivity": sensitivity.prepare, "pareto": sensitivity.prepare}
"""Figure key → function(run) that does the figure's costly work on a run (its replays) in
the process that ran the experiment, keeping the result on the run."""
