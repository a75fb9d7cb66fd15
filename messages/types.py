"""The message types of the slipstack graph (ARCHITECTURE.md, topic table).

SI units throughout; ``F`` is the pad frame of MATH.md §1. Array fields give their
dtype and shape; ``N`` is the number of taxels (rows × cols, row-major).
"""

from __future__ import annotations

from dataclasses import field

import numpy as np

from slipstack.messages.base import Message, array, message

__all__ = [
    "Wrench", "TactileFrame", "Contact", "Cor", "Slip", "GripCommand", "RigTruth",
    "Diagnostics", "STATUS_OK",
]

STATUS_OK = "ok"


@message("slipstack/Wrench")
class Wrench(Message):
    """``ft/wrench``: one F/T sample.

    force: (3,) N and torque: (3,) N·m, in ``frame`` (``"sensor"`` as the device
    reports it, or ``"pad"`` when the driver applied the sensor-to-pad transform).
    device_seq: the device's own sample counter (−1 if it has none).
    status: ``ok`` | ``stale`` | ``disconnected`` | ``overrange`` | free text.
    """

    force: np.ndarray = array("<f8", (3,), doc="N")
    torque: np.ndarray = array("<f8", (3,), doc="N·m")
    frame: str = "sensor"
    device_seq: int = -1
    status: str = STATUS_OK


@message("slipstack/TactileFrame")
class TactileFrame(Message):
    """``tactile/frame``: one calibrated tactile image.

    pressure_pa: (N,) float32 Pa, row-major (row 0 first); dead taxels carry 0.
    saturated: (N,) bool, raw counts at or above the saturation level.
    dead: (N,) bool, taxels masked out by calibration.
    """

    rows: int = 16
    cols: int = 16
    pitch_m: float = 1.25e-3
    pressure_pa: np.ndarray = array("<f4", (None,), doc="Pa")
    saturated: np.ndarray = array("|b1", (None,))
    dead: np.ndarray = array("|b1", (None,))
    device_stamp: int = -1
    status: str = STATUS_OK


@message("slipstack/Contact", version=2)  # 2: tactile_status
class Contact(Message):
    """``contact``: fused contact state in the pad frame ``F`` (MATH.md §2).

    phi: (N,) N, local normal force per taxel, Σφ = f_n.
    f_n: N; f_t: (2,) N; tau: N·m about z through the pad origin.
    cop: (2,) m, centre of pressure. area_m2: contact area. mask: (N,) bool.
    pair_offset_ns: tactile stamp minus F/T stamp of the paired samples.
    has_tactile: a tactile frame was paired (``phi``, ``mask`` and ``cop`` come from it).
    tactile_status: why not, when not: ``ok`` (paired), ``off`` (the stack runs without
    tactile), ``none`` (no frame yet), ``unpaired`` (the newest frame is older or newer
    than the pairing window), or the frame's own status (``stale``, ``disconnected`` …).
    status: the F/T sample's status, or fusion's (``ok``, ``no_contact``,
    ``invalid_input``, ``implausible``: the pad is pressed far harder than the F/T
    sensor reports, as a biased or spoofed F/T sensor would).
    header.sources holds both stamps (``ft``, ``tactile``).
    """

    rows: int = 16
    cols: int = 16
    pitch_m: float = 1.25e-3
    phi: np.ndarray = array("<f8", (None,), doc="N")
    f_n: float = 0.0
    f_t: np.ndarray = array("<f8", (2,), doc="N")
    tau: float = 0.0
    cop: np.ndarray = array("<f8", (2,), doc="m")
    area_m2: float = 0.0
    mask: np.ndarray = array("|b1", (None,))
    pair_offset_ns: int = 0
    has_tactile: bool = True
    status: str = STATUS_OK
    tactile_status: str = STATUS_OK


@message("slipstack/Cor")
class Cor(Message):
    """``cor``: centre of rotation of impending slip.

    case: ``rotation`` | ``translation`` | ``on-taxel`` | ``none``.
    p_c: (2,) m in ``F`` (zeros when case is translation or none).
    torque_capacity: T(p_c) N·m; load_torque: n(p_c) N·m.
    gamma: load factor (≤ 1 sticks); +inf for a load no friction can hold.
    """

    case: str = "none"
    p_c: np.ndarray = array("<f8", (2,), doc="m")
    torque_capacity: float = 0.0
    load_torque: float = 0.0
    gamma: float = field(default=0.0, metadata={"allow_inf": True})
    iterations: int = 0
    residual: float = field(default=0.0, metadata={"allow_inf": True})
    converged: bool = False
    status: str = STATUS_OK


@message("slipstack/Slip")
class Slip(Message):
    """``slip``: the slip verdict.

    state: ``stick`` | ``translation`` | ``rotation`` | ``combined`` | ``no-contact``.
    margin: 1 − γ or the method's analogue (> 0 sticks).
    verdicts: per method name, ``[stick: bool, margin: float]``.
    f_n (N), f_t (2,) N, tau (N·m, about z through the pad origin): the load the
    verdict judged, in ``F`` — so a grip law needs no second subscription.
    p_c: (2,) m, the COR of impending slip the method found (valid if ``p_c_valid``).
    """

    state: str = "no-contact"
    margin: float = field(default=0.0, metadata={"allow_inf": True})
    method: str = ""
    verdicts: dict = field(default_factory=dict)
    gamma: float = field(default=0.0, metadata={"allow_inf": True})
    status: str = STATUS_OK
    f_n: float = 0.0
    f_t: np.ndarray = array("<f8", (2,), doc="N")
    tau: float = 0.0
    p_c: np.ndarray = array("<f8", (2,), doc="m")
    p_c_valid: bool = False


@message("slipstack/GripCommand")
class GripCommand(Message):
    """``grip/command``: desired normal force f_n (N) and why."""

    f_n_desired: float = 0.0
    law: str = ""
    reason: str = "nominal"


@message("slipstack/RigTruth")
class RigTruth(Message):
    """``rig/truth``: the simulated rig's ground truth, object relative to the pad.

    x, y: m; theta: rad; vx, vy: m/s; omega: rad/s; cor: (2,) m (valid if cor_valid).
    gross_slip: the whole contact slides. slip_distance_m / slip_angle_rad: totals.
    f_n_applied / f_n_command: N, the finger's actual and commanded normal force.
    sliding_fraction: share of the friction capacity used by sliding taxels (0..1).
    load_f_t (2,) N, load_tau N·m: the load the contact transmits to the object, in F.
    """

    x: float = 0.0
    y: float = 0.0
    theta: float = 0.0
    vx: float = 0.0
    vy: float = 0.0
    omega: float = 0.0
    gross_slip: bool = False
    cor: np.ndarray = array("<f8", (2,), doc="m")
    cor_valid: bool = False
    slip_distance_m: float = 0.0
    slip_angle_rad: float = 0.0
    f_n_applied: float = 0.0
    f_n_command: float = 0.0
    sliding_fraction: float = 0.0
    load_f_t: np.ndarray = array("<f8", (2,), doc="N")
    load_tau: float = 0.0


@message("slipstack/Diagnostics")
class Diagnostics(Message):
    """``diagnostics``: a node's counters (drops, rejects, rates, latencies).

    counters: flat map ``name -> number``; names are ``in.<topic>.received``,
    ``in.<topic>.dropped``, ``in.<topic>.rejected``, ``in.<topic>.lost`` (sequence
    gaps), ``out.<topic>.published``, ``handler.p50_us``…, plus node-specific ones.
    last_error: the newest rejected frame's reason, '' if none.
    """

    node: str = ""
    status: str = STATUS_OK
    counters: dict = field(default_factory=dict)
    last_error: str = ""
