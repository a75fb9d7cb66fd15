"""The one code default of each physical constant of the stack.

Used where the code needs a value that no launch file (``launch/files/``) or material
file (``launch/materials/``) gave: the library's tests and laws built without one,
the nodes' parameter defaults. A launch run takes μ from its material file and f_max
from its launch arguments; those are the places to change them.
"""

from __future__ import annotations

__all__ = ["MU", "F_MAX_N"]

MU = 0.45
"""Static friction coefficient (dimensionless) of the paper's experiments (§V, docs/math.md §5)."""

F_MAX_N = 20.0
"""Highest normal force the grip controller commands (N): the simulated finger's limit."""
