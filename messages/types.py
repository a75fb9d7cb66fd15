"""The message types of the slipstack graph (docs/architecture.md §3).

SI units throughout; ``F`` is the pad frame of docs/math.md §1. Array fields give their
dtype and shape; ``N`` is the number of taxels (rows × cols, row-major).

Declared bounds (checked on decode, by ``topic pub``, written into the exported
schemas): pads of at most :data:`MAX_PAD_SIDE` × :data:`MAX_PAD_SIDE` taxels whose
arrays hold exactly rows × cols values, a taxel pitch in (0, :data:`MAX_PITCH_M`],
a commanded grip in [0, :data:`MAX_GRIP_FORCE_N`] N, enumerated frames, slip states
and COR cases, and data statuses from :data:`STATUSES` (or a device status code).
"""

from __future__ import annotations

from dataclasses import field

import numpy as np

from slipstack.lib.status import SAMPLE_NO_CONTACT, SAMPLE_OK, SAMPLE_UNUSABLE, SlipCase, SlipState, SolverStatus
from slipstack.messages.base import Bounds, Message, array, bounded, message

__all__ = [
    "Wrench", "TactileFrame", "Contact", "Cor", "Slip", "GripCommand", "GripState", "FINGER_MODES", "RigTruth",
    "Diagnostics", "STATUS_OK", "STATUSES", "TACTILE_PAIRING", "DEVICE_STATUS_PATTERN", "NAME_PATTERN", "MAX_PAD_SIDE",
    "MAX_PITCH_M", "MAX_GRIP_FORCE_N", "MAX_TEXT_LEN", "MAX_COUNTERS", "MAX_VERDICTS", "MAX_EARLIER_SAMPLES",
    "SAMPLE_OK", "SAMPLE_NO_CONTACT", "SAMPLE_UNUSABLE",
]

STATUS_OK = "ok"
TACTILE_PAIRING = (STATUS_OK, "off", "none", "unpaired", "stale", "disconnected", "taring", "fault")
"""Why a contact has no tactile frame (``Contact.tactile_status``): ``ok`` it has one;
``off`` the stack runs without tactile; ``none`` no frame yet; ``unpaired`` the newest
frame is outside the pairing window; the frame's own link status; ``fault`` any other
status the frame carried."""
STATUSES = tuple(dict.fromkeys([
    STATUS_OK, "stale", "disconnected", "taring",  # device links and drivers (nodes/devices)
    *(s.value for s in SolverStatus),  # fusion and the solvers (lib/status.py), passed on downstream
    "implausible",  # fusion: the pad is pressed far harder than the F/T sensor reports
    *(f"tactile_{p}" for p in TACTILE_PAIRING[1:]),  # slip: a tactile test without a paired frame
    "below_noise",  # slip: a capacity the F/T's noise swamps (lib/detector.py)
]))
"""Status of a data message (``ok``: usable): what the drivers, fusion and the solvers produce."""
DEVICE_STATUS_PATTERN = r"device-status 0x[0-9a-f]{4,8}"
"""A device's own nonzero status word, as the F/T driver reports it (e.g. ``device-status 0x0002``)."""
NAME_PATTERN = r"[A-Za-z0-9_.+-]*"
"""Identifiers: grip law, reason, slip-test method names."""
MAX_PAD_SIDE = 256
"""Rows and columns of a tactile pad, each at most (a 256×256 pad: 65 536 taxels)."""
MAX_PITCH_M = 0.1
"""Largest taxel pitch, m."""
MAX_GRIP_FORCE_N = 1000.0
"""Largest normal force a grip command may ask for, N."""
MAX_TEXT_LEN = 4096
"""Characters of free text (a diagnostics status detail or error)."""
MAX_COUNTERS = 4096
"""Entries of a diagnostics counter map."""
MAX_VERDICTS = 32
"""Entries of a slip verdict map (one per slip test)."""
MAX_EARLIER_SAMPLES = 63
"""F/T samples a contact carries besides its newest (``Contact.earlier_*``): fusion's batch
of at most 64 samples per wake-up, 9 ms at the Net F/T's 7 kHz."""

_SIDE = {"ge": 1, "le": MAX_PAD_SIDE}
_STATUS = {"choices": STATUSES, "pattern": DEVICE_STATUS_PATTERN, "max_len": 64}
_NAME = {"pattern": NAME_PATTERN, "max_len": 64}


@message("slipstack/Wrench")
class Wrench(Message):
    """``ft/wrench``: one F/T sample.

    force: (3,) N and torque: (3,) N·m, in ``frame`` (``"sensor"`` as the device
    reports it, or ``"pad"`` when the driver applied the sensor-to-pad transform).
    device_seq: the device's own sample counter (−1 if it has none).
    status: one of :data:`STATUSES` (``ok``, ``stale``, ``disconnected``, ``taring`` …)
    or ``device-status 0xNNNN`` (the device flagged the sample).
    """

    force: np.ndarray = array("<f8", (3,), doc="N")
    torque: np.ndarray = array("<f8", (3,), doc="N·m")
    frame: str = bounded("sensor", choices=("sensor", "pad"))
    device_seq: int = bounded(-1, ge=-1)
    status: str = bounded(STATUS_OK, **_STATUS)


@message("slipstack/TactileFrame")
class TactileFrame(Message):
    """``tactile/frame``: one calibrated tactile image.

    rows, cols: 1 … :data:`MAX_PAD_SIDE` each; pitch_m: m, in (0, :data:`MAX_PITCH_M`].
    pressure_pa: (N,) float32 Pa, row-major (row 0 first); dead taxels carry 0.
    saturated: (N,) bool, raw counts at or above the saturation level.
    dead: (N,) bool, taxels masked out by calibration.
    device_stamp: the device's own clock, ns; -1 for a device without one.
    """

    rows: int = bounded(16, **_SIDE)
    cols: int = bounded(16, **_SIDE)
    pitch_m: float = bounded(1.25e-3, gt=0.0, le=MAX_PITCH_M, doc="m")
    pressure_pa: np.ndarray = array("<f4", ("rows*cols",), doc="Pa")
    saturated: np.ndarray = array("|b1", ("rows*cols",))
    dead: np.ndarray = array("|b1", ("rows*cols",))
    device_stamp: int = -1
    status: str = bounded(STATUS_OK, **_STATUS)


@message("slipstack/Contact", version=3, reads_older={2: "earlier_samples"})  # 2: tactile_status; 3: earlier_*
class Contact(Message):
    """``contact``: fused contact state in the pad frame ``F`` (docs/math.md §2).

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
    rows, cols, pitch_m: the pad's, or 0 for an F/T-only contact (then N = 0).

    The fields above describe the newest F/T sample of fusion's wake-up. The
    ``earlier_samples`` (m, 0 … :data:`MAX_EARLIER_SAMPLES`) samples that arrived with
    it, oldest first, carry their loads in the same pad frame ``F``, paired with the
    same tactile frame (its pressure shape scaled to each sample's normal force):
    earlier_stamp_ns (m,) ns; earlier_f_n (m,) N (≥ 0); earlier_f_tx, earlier_f_ty
    (m,) N; earlier_tau (m,) N·m about z through the pad origin; earlier_status (m,)
    uint8: :data:`SAMPLE_OK`, :data:`SAMPLE_NO_CONTACT` or :data:`SAMPLE_UNUSABLE`.
    ``status`` is the newest sample's, unless that one is ``ok`` or ``no_contact`` and
    an earlier one is unusable: then the first unusable earlier sample's status, so no
    consumer lowers the grip on a wake-up that held a bad sample. A version 2 contact
    (recorded before the earlier samples existed) reads as one without earlier samples.
    """

    rows: int = bounded(16, ge=0, le=MAX_PAD_SIDE)
    cols: int = bounded(16, ge=0, le=MAX_PAD_SIDE)
    pitch_m: float = bounded(1.25e-3, ge=0.0, le=MAX_PITCH_M, doc="m")
    phi: np.ndarray = array("<f8", ("rows*cols",), doc="N")
    f_n: float = bounded(0.0, doc="N")
    f_t: np.ndarray = array("<f8", (2,), doc="N")
    tau: float = bounded(0.0, doc="N·m")
    cop: np.ndarray = array("<f8", (2,), doc="m")
    area_m2: float = bounded(0.0, ge=0.0, doc="m²")
    mask: np.ndarray = array("|b1", ("rows*cols",))
    pair_offset_ns: int = bounded(0, doc="ns")
    has_tactile: bool = True
    status: str = bounded(STATUS_OK, **_STATUS)
    tactile_status: str = bounded(STATUS_OK, choices=TACTILE_PAIRING)
    earlier_samples: int = bounded(0, ge=0, le=MAX_EARLIER_SAMPLES)
    earlier_stamp_ns: np.ndarray = array("<i8", ("earlier_samples",), doc="ns")
    earlier_f_n: np.ndarray = array("<f8", ("earlier_samples",), doc="N")
    earlier_f_tx: np.ndarray = array("<f8", ("earlier_samples",), doc="N")
    earlier_f_ty: np.ndarray = array("<f8", ("earlier_samples",), doc="N")
    earlier_tau: np.ndarray = array("<f8", ("earlier_samples",), doc="N·m")
    earlier_status: np.ndarray = array("|u1", ("earlier_samples",))


@message("slipstack/Cor")
class Cor(Message):
    """``cor``: centre of rotation of impending slip.

    case: ``rotation`` | ``translation`` | ``on-taxel`` | ``none``.
    p_c: (2,) m in ``F`` (zeros when case is translation or none).
    torque_capacity: T(p_c) N·m; load_torque: n(p_c) N·m.
    gamma: load factor (≤ 1 sticks); +inf for a load no friction can hold.
    """

    case: str = bounded(SlipCase.NONE.value, choices=tuple(c.value for c in SlipCase))
    p_c: np.ndarray = array("<f8", (2,), doc="m")
    torque_capacity: float = bounded(0.0, doc="N·m")
    load_torque: float = bounded(0.0, doc="N·m")
    gamma: float = bounded(0.0, allow_inf=True)
    iterations: int = 0
    residual: float = bounded(0.0, allow_inf=True)
    converged: bool = False
    status: str = bounded(STATUS_OK, **_STATUS)


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

    state: str = bounded(SlipState.NO_CONTACT.value, choices=tuple(s.value for s in SlipState))
    margin: float = bounded(0.0, allow_inf=True)
    method: str = bounded("", **_NAME)
    verdicts: dict = field(default_factory=dict, metadata={"bounds": Bounds(max_len=MAX_VERDICTS),
                                                           "values": (bool, float)})
    gamma: float = bounded(0.0, allow_inf=True)
    status: str = bounded(STATUS_OK, **_STATUS)
    f_n: float = bounded(0.0, doc="N")
    f_t: np.ndarray = array("<f8", (2,), doc="N")
    tau: float = bounded(0.0, doc="N·m")
    p_c: np.ndarray = array("<f8", (2,), doc="m")
    p_c_valid: bool = False


@message("slipstack/GripCommand")
class GripCommand(Message):
    """``grip/command``: desired normal force f_n (N, 0 … :data:`MAX_GRIP_FORCE_N`) and why."""

    f_n_desired: float = bounded(0.0, ge=0.0, le=MAX_GRIP_FORCE_N, doc="N")
    law: str = bounded("", **_NAME)
    reason: str = bounded("nominal", **_NAME)


FINGER_MODES = ("initial", "following", "watchdog")
"""What the finger's grip is (``GripState.mode``): ``initial`` its own since power-on, no command
yet; ``following`` the last ``grip/command``; ``watchdog`` commands stopped, it holds (and may raise)."""


@message("slipstack/GripState")
class GripState(Message):
    """``grip/state``: what the finger reports (docs/safety.md, the start contract).

    f_n_command: the normal force it holds to now (N). mode: one of :data:`FINGER_MODES`.
    commanded_by: who sent the command it follows: "" the graph's controller, else the
    injecting tool's name (a manual command, where the launch allows it).
    """

    f_n_command: float = bounded(0.0, ge=0.0, le=MAX_GRIP_FORCE_N, doc="N")
    mode: str = bounded("initial", choices=FINGER_MODES)
    commanded_by: str = bounded("", pattern=NAME_PATTERN, max_len=64)


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
    status and last_error are free text of at most :data:`MAX_TEXT_LEN` characters.
    """

    node: str = bounded("", max_len=128)
    status: str = bounded(STATUS_OK, max_len=MAX_TEXT_LEN)
    counters: dict = field(default_factory=dict, metadata={"bounds": Bounds(max_len=MAX_COUNTERS), "values": float})
    last_error: str = bounded("", max_len=MAX_TEXT_LEN)
