"""Sensor samples: one F/T reading, one tactile frame, one gripper force reading — as a
device back-end decodes them and as the simulated rig's sensor models produce them.

``stamp_ns`` is the time of the sample on the clock of whoever made it: the
simulated time for the rig's sensor models, the caller's clock at the ``poll()`` that
decoded it for a device back-end.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["FtSample", "TactileSample", "GripperSample", "MAX_SAMPLE_RATE_HZ"]

MAX_SAMPLE_RATE_HZ = 10_000.0
"""The fastest sensor stream accepted (Hz), simulated or read: above the fastest the drivers
know (ATI RDT, 7 kHz); a rate beyond it is a typo (1e12 made a lock-step run hang)."""


@dataclass(frozen=True, slots=True)
class FtSample:
    """One force/torque sample in the sensor frame ``S``.

    stamp_ns: time of the sample (ns, see the module docstring).
    force_n: (3,) float64, N. torque_nm: (3,) float64, N·m about the sensor origin.
    device_seq: the sensor's sample counter (RDT ``rdt_sequence``; the simulated
        sensor counts from 0), or None.
    device_time_s: device clock (Bota timestamp) in s, or None.
    status: device status word, 0 = no flag (RDT status, Bota status bits).
    saturated: some axis hit its range and the value is clipped (the simulated
        sensor says so here; a device says so in ``status``).
    finger: which finger's sensor (0, or 1 on the simulated gripper's second finger).
    """

    stamp_ns: int
    force_n: np.ndarray
    torque_nm: np.ndarray
    device_seq: int | None = None
    device_time_s: float | None = None
    status: int = 0
    saturated: bool = False
    finger: int = 0


@dataclass(frozen=True, slots=True)
class TactileSample:
    """One tactile frame: raw counts, shape (rows, cols), uint16, row = y, col = x.

    stamp_ns: time of the frame (ns, see the module docstring).
    device_time_s: controller clock (DSACON32 ms timestamp) in s, or None.
    device_seq: the frame counter (the simulated sensor counts from 0; no tactile
        protocol has one), or None.
    status: device flags, 0 = none.
    finger: which finger's pad (0, or 1 on the simulated gripper's second finger).
    """

    stamp_ns: int
    counts: np.ndarray
    device_time_s: float | None = None
    device_seq: int | None = None
    status: int = 0
    finger: int = 0


@dataclass(frozen=True, slots=True)
class GripperSample:
    """One reading of a gripper's grasping force.

    stamp_ns: time of the sample (ns, see the module docstring).
    force_n: the grasping force the gripper measures (N).
    force_limit_n: the force limit it was last told, and acknowledged (N; NaN before any).
    state: its grasping state (``holding``, ``idle``, ...; lib/protocols/wsg.py).
    """

    stamp_ns: int
    force_n: float
    force_limit_n: float
    state: str
