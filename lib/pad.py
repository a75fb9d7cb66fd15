"""Tactile pad geometry: taxel positions in the pad frame and pooling.

Pad frame ``F`` (docs/math.md §1): origin at the pad centre, ``x`` along columns,
``y`` along rows, ``z`` the outward normal. Taxel ``i`` at row ``r``, column ``k``
sits at ``p_i = ((k - (C-1)/2)·h, (r - (R-1)/2)·h)`` metres; row-major order,
row 0 first.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from slipstack.lib.errors import ConfigError

__all__ = ["PadGeometry", "PadMount"]


@dataclass(frozen=True)
class PadGeometry:
    """A rectangular taxel grid.

    Attributes:
        rows: number of taxel rows ``R`` (along ``y``).
        cols: number of taxel columns ``C`` (along ``x``).
        pitch_m: centre-to-centre taxel spacing ``h`` in metres.
    """

    rows: int = 16
    cols: int = 16
    pitch_m: float = 1.25e-3

    def __post_init__(self) -> None:
        if self.rows < 1 or self.cols < 1:
            raise ConfigError(f"pad needs rows, cols >= 1, got {self.rows}x{self.cols}")
        if not (np.isfinite(self.pitch_m) and self.pitch_m > 0):
            raise ConfigError(f"pad pitch must be a positive length in metres, got {self.pitch_m}")

    @property
    def n_taxels(self) -> int:
        """Number of taxels ``R·C``."""
        return self.rows * self.cols

    @property
    def taxel_area_m2(self) -> float:
        """Area of one taxel cell ``h²`` in m²."""
        return self.pitch_m * self.pitch_m

    @cached_property
    def positions(self) -> np.ndarray:
        """Taxel centres ``p_i`` in the pad frame, shape ``(R·C, 2)``, metres, row-major."""
        k = (np.arange(self.cols) - (self.cols - 1) / 2.0) * self.pitch_m
        r = (np.arange(self.rows) - (self.rows - 1) / 2.0) * self.pitch_m
        xx, yy = np.meshgrid(k, r)  # yy varies along rows
        pos = np.column_stack([xx.ravel(), yy.ravel()])
        pos.setflags(write=False)
        return pos

    def pooled(self, block: int) -> "PadGeometry":
        """The coarser pad obtained by pooling ``block × block`` taxels into one.

        Raises:
            ConfigError: if ``block`` does not divide both ``rows`` and ``cols``.
        """
        if block < 1 or self.rows % block or self.cols % block:
            raise ConfigError(
                f"pooling block {block} must divide the pad size {self.rows}x{self.cols}"
            )
        return PadGeometry(self.rows // block, self.cols // block, self.pitch_m * block)

    def pool(self, values: np.ndarray, block: int) -> np.ndarray:
        """Sum per-taxel values (forces, N) over ``block × block`` blocks.

        Args:
            values: shape ``(R·C,)`` or ``(R, C)``, row-major.
            block: pooling factor; must divide ``rows`` and ``cols``.

        Returns:
            Shape ``((R/block)·(C/block),)``, the summed values, row-major. Summing
            keeps ``f_n`` and the centre of pressure of each block's total exact
            at the pooled taxel's centre.
        """
        coarse = self.pooled(block)
        grid = np.asarray(values, dtype=float).reshape(self.rows, self.cols)
        summed = grid.reshape(coarse.rows, block, coarse.cols, block).sum(axis=(1, 3))
        return summed.ravel()


@dataclass(frozen=True)
class PadMount:
    """How the tactile array is mounted on the pad: its image in the pad frame ``F``.

    The device sends its image in its own rows and columns. ``flip_rows`` mirrors it
    along ``y`` (row ``r`` → ``R−1−r``), ``flip_cols`` along ``x``; then
    ``quarter_turns`` (0–3) turns it counter-clockwise about ``z`` by 90° each, as seen
    with ``x`` right and ``y`` up: a taxel at ``(x, y)`` moves to ``(−y, x)``. An odd
    number of turns swaps rows and columns.
    """

    flip_rows: bool = False
    flip_cols: bool = False
    quarter_turns: int = 0

    def __post_init__(self) -> None:
        if self.quarter_turns not in (0, 1, 2, 3):
            raise ConfigError(f"pad mount quarter_turns must be 0, 1, 2 or 3, got {self.quarter_turns!r}")

    @property
    def identity(self) -> bool:
        """True when the image needs no change."""
        return not (self.flip_rows or self.flip_cols or self.quarter_turns)

    def shape(self, rows: int, cols: int) -> tuple[int, int]:
        """(rows, cols) of the image in ``F`` for a device image of ``rows × cols``."""
        return (cols, rows) if self.quarter_turns % 2 else (rows, cols)

    def apply(self, image: np.ndarray) -> np.ndarray:
        """The device image (rows × cols, any dtype) as seen in the pad frame (a view or copy)."""
        out = image[::-1, :] if self.flip_rows else image
        out = out[:, ::-1] if self.flip_cols else out
        # (r, c) -> (c, R-1-r) per turn is numpy's clockwise rot90 in index terms, which is
        # counter-clockwise in F (rows grow along +y)
        return np.rot90(out, -self.quarter_turns) if self.quarter_turns else out
