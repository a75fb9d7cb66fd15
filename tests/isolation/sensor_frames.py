"""Hand-made sensor frames for the node-level tests: F/T samples and tactile frames on
the 16×16 pad, stamped in simulated milliseconds, as ``(t_ns, topic, message)`` events
for :class:`~slipstack.nodes.runtime.inprocess.InProcessExecutor`."""

from __future__ import annotations

import numpy as np

from slipstack.messages import GripState, Header, TactileFrame, Wrench

__all__ = ["COLS", "MS", "PITCH_M", "ROWS", "finger", "pressure_for", "tactile", "wrench"]

MS = 1_000_000
"""Nanoseconds per millisecond."""
ROWS = COLS = 16
PITCH_M = 1.25e-3


def _stamp_ns(t_ms: float, stamp_ms: float | None, stamp_ns: int | None) -> int:
    if stamp_ns is not None:
        return stamp_ns
    return round((t_ms if stamp_ms is None else stamp_ms) * MS)


def wrench(t_ms: float, f_n: float, f_t: float, *, seq: int = 0, status: str = "ok", stamp_ms: float | None = None,
           stamp_ns: int | None = None, frame: str = "pad", tau: float = 0.0) -> tuple[int, str, Wrench]:
    """An F/T sample received at ``t_ms`` pressing with ``f_n`` N, pulling with ``f_t`` N
    along x and twisting with ``tau`` N·m about z (frame ``frame``); stamped at
    ``stamp_ns``, else ``stamp_ms``, else ``t_ms``."""
    stamp = _stamp_ns(t_ms, stamp_ms, stamp_ns)
    msg = Wrench(force=np.array([f_t, 0.0, -f_n]), torque=np.array([0.0, 0.0, tau]), frame=frame, status=status,
                 header=Header(stamp, seq, stamp, {}))
    return round(t_ms * MS), "ft/wrench", msg


def pressure_for(f_n: float) -> np.ndarray:
    """A centred 6×6 patch of uniform pressure (Pa) whose total force is ``f_n`` N."""
    p = np.zeros((ROWS, COLS), dtype=np.float32)
    p[5:11, 5:11] = f_n / (36 * PITCH_M**2)
    return p.reshape(-1)


def tactile(t_ms: float, f_n: float, *, seq: int = 0, status: str = "ok", stamp_ms: float | None = None,
            stamp_ns: int | None = None, pressure_pa: np.ndarray | None = None) -> tuple[int, str, TactileFrame]:
    """A tactile frame received at ``t_ms``: :func:`pressure_for` ``f_n``, or ``pressure_pa``
    (Pa, ROWS·COLS taxels) when given; stamped as :func:`wrench`."""
    stamp = _stamp_ns(t_ms, stamp_ms, stamp_ns)
    n = ROWS * COLS
    pressure = pressure_for(f_n) if pressure_pa is None else np.asarray(pressure_pa, dtype=np.float32)
    msg = TactileFrame(rows=ROWS, cols=COLS, pitch_m=PITCH_M, pressure_pa=pressure,
                       saturated=np.zeros(n, bool), dead=np.zeros(n, bool), status=status,
                       header=Header(stamp, seq, stamp, {}))
    return round(t_ms * MS), "tactile/frame", msg


def finger(t_ms: float, f_n: float, mode: str = "following") -> tuple[int, str, GripState]:
    """The finger's report at ``t_ms``: it holds to ``f_n`` N, in ``mode`` (``initial``: never commanded)."""
    stamp = round(t_ms * MS)
    return stamp, "grip/state", GripState(f_n_command=f_n, mode=mode, header=Header(stamp, 0, stamp, {}))
