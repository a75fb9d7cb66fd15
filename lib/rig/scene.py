"""Scene files: a simulated experiment as frozen dataclasses, loaded from TOML.

A scene (docs/architecture.md §6) says which object is pressed by the pad, how the
pressure is distributed, which degrees of freedom move, what the disturbance motor
does, and how the sensors behave. Units are SI throughout (N, N·m, m, s, Pa); vectors
in the pad frame ``F`` of docs/math.md §1. The loader is strict: an unknown key, a wrong
type or an out-of-range value raises :class:`ConfigError` naming the key, e.g.
``fig10.toml: contact.mu_d: must be <= contact.mu_s (0.45), got 0.5``.

More in docs/modules.md, `lib/rig/scene.py`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Callable, Mapping

from slipstack.lib.config import REQUIRED, ConfigTable
from slipstack.lib.errors import ConfigError
from slipstack.lib.toml_file import read_toml
from slipstack.lib.pad import PadGeometry
from slipstack.lib.samples import MAX_SAMPLE_RATE_HZ

__all__ = [
    "MAX_SUBSAMPLES",
    "ObjectSpec",
    "ContactSpec",
    "DofSpec",
    "FingerSpec",
    "Segment",
    "DisturbanceSpec",
    "SupportSpec",
    "FtSpec",
    "TactileSpec",
    "SimSpec",
    "ExpectSpec",
    "MassStep",
    "GripperSpec",
    "Scene",
    "load_scene",
    "parse_scene",
    "PRESSURE_MODELS",
    "SEGMENT_KINDS",
    "RIG_MATERIALS",
    "with_rig_material",
    "mirrored_contact",
]

MAX_SUBSAMPLES = 11
"""Most sample points per taxel side: 121 per taxel, within the 128 that the compiled
pressure sampling sums in numpy's order (lib/rig/pressure_kernels.py)."""

PRESSURE_MODELS = ("flat", "hertz", "offset", "edge")
RIG_MATERIALS: dict[str, tuple[float, float]] = {
    "rubber": (0.45, 0.36),     # the rig's slip-weakening rubber, mu_d/mu_s = 0.8
    "coulomb": (0.45, 0.45),    # no weakening: mu_d = mu_s
    "weakening": (0.50, 0.30),  # strongly weakening, mu_d/mu_s = 0.6
}
"""The rig's contact materials, ``name → (μ_s, μ_d)``; a scene picks one with
``[contact] material = "coulomb"`` (its ``mu_s``/``mu_d`` keys, if given, win)."""
SEGMENT_KINDS = ("hold", "step", "ramp", "sine")
DOF_NAMES = ("x", "y", "theta")
Vec2 = tuple[float, float]
Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class ObjectSpec:
    """The rigid planar object under the pad.

    Attributes:
        mass_kg: mass ``m`` (kg), including whatever the disturbance motor drags along.
        inertia_kgm2: moment of inertia about the centre of mass, about ``z`` (kg·m²).
        pose: initial ``(x, y, θ)`` of the centre of mass in ``F`` (m, m, rad).
    """

    mass_kg: float = 0.2
    inertia_kgm2: float = 4e-5
    pose: Vec3 = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class ContactSpec:
    """Pressure model and per-taxel friction ("bristle") model.

    Friction (lib/rig/friction.py): each taxel patch is an elastic bristle of shear
    stiffness ``stiffness_N_per_m3·h²`` (N/m) and damping ``damping_Ns_per_m3·h²``
    (N·s/m), sticking up to ``μ_s,i φ_i`` and sliding at ``μ_i(s) φ_i`` with the
    slip-weakening law ``μ_i(s) = μ_d,i + (μ_s,i − μ_d,i)·exp(−s/slip_weakening_m)``,
    ``s`` the distance the patch has slid since it last stuck. ``μ_s,i`` and
    ``μ_d,i`` are ``mu_s``, ``mu_d`` times a per-taxel factor ``1 + mu_spread·N(0,1)``
    drawn from the scene seed (surface heterogeneity).

    Pressure (lib/rig/contact.py), by ``model``:
        flat: uniform over a footprint (``footprint`` = "pad" | "disc" | "rect",
            ``centre_m``, ``radius_m``, ``half_size_m``).
        offset: a footprint as for flat with a linear pressure gradient
            ``slope_per_m`` (relative change of pressure per metre, a tilted face).
        hertz: curved fingertip, ``p ∝ sqrt(1 − r²/a²)``, ``a = a_ref_m·(f_n/f_ref_N)^{1/3}``
            centred at ``centre_m``.
        edge: an object edge, a strip of length ``length_m`` at ``angle_rad`` through
            ``centre_m`` with a Hertzian line-contact profile across it of half-width
            ``b = b_ref_m·(f_n/f_ref_N)^{1/2}``.
    The flat and offset models may carry ridges (a grooved face): the pressure times
    ``1 + ridge_depth·cos(2π d·n/ridge_period_m)``, ``n`` at ``ridge_angle_rad`` across the
    ridges; ``ridge_depth = 0`` (default) has none.
    ``moves_with_object`` (default: true except hertz) makes the footprint a part of the
    object, so the pressure image translates and rotates on the pad when it slips.
    ``subsamples``² points per taxel sample the pressure (small contacts do not alias);
    at most ``MAX_SUBSAMPLES`` (11: 121 points per taxel).
    """

    model: str = "flat"
    mu_s: float = 0.45
    mu_d: float = 0.36
    mu_spread: float = 0.02
    slip_weakening_m: float = 1e-4
    stiffness_N_per_m3: float = 1e8
    damping_Ns_per_m3: float = 1.5e5
    stick_speed_m_s: float = 1e-4
    regularisation_speed_m_s: float = 1e-6
    subsamples: int = 4
    moves_with_object: bool | None = None
    footprint: str = "pad"
    centre_m: Vec2 = (0.0, 0.0)
    radius_m: float = 5e-3
    half_size_m: Vec2 = (5e-3, 5e-3)
    slope_per_m: Vec2 = (0.0, 0.0)
    a_ref_m: float = 5e-3
    b_ref_m: float = 1e-3
    f_ref_N: float = 5.0
    length_m: float = 15e-3
    angle_rad: float = 0.0
    ridge_depth: float = 0.0
    ridge_period_m: float = 5e-3
    ridge_angle_rad: float = 0.0

    @property
    def attached_to_object(self) -> bool:
        """Whether the pressure footprint moves with the object (model default if unset)."""
        if self.moves_with_object is None:
            return self.model != "hertz"
        return self.moves_with_object


@dataclass(frozen=True)
class DofSpec:
    """Free degrees of freedom of the object relative to the pad.

    ``free`` is a non-empty subset of ("x", "y", "theta"); the others are not
    integrated at all. ``pivot_m`` (only with ``free = ("theta",)``) is a fixed axis
    in ``F`` the object rotates about (the paper's Fig. 13 rig); without it a
    rotation-only object turns about its centre of mass.
    """

    free: tuple[str, ...] = DOF_NAMES
    pivot_m: Vec2 | None = None


@dataclass(frozen=True)
class FingerSpec:
    """Finger actuator: commanded normal force → applied ``f_n`` (N).

    First-order lag of bandwidth ``bandwidth_hz``, rate limit ``rate_N_per_s``,
    saturation to ``[0, f_max_N]``; starts at ``f_initial_N`` (also the command until
    :meth:`Simulator.command_normal_force` is called).
    """

    f_initial_N: float = 5.0
    bandwidth_hz: float = 20.0
    rate_N_per_s: float = 100.0
    f_max_N: float = 20.0


@dataclass(frozen=True)
class Segment:
    """One piece of a disturbance profile, on three channels.

    Channels are ``(f_x N, f_y N, τ N·m)`` in wrench mode and the motor displacement
    ``(x m, y m, θ rad)`` in drag mode. Kinds: ``hold`` keeps the current value;
    ``step`` jumps to ``target`` and holds; ``ramp`` goes linearly to ``target``;
    ``sine`` adds ``amplitude·sin(2π f t)`` to the current value and ends back on it.
    """

    kind: str
    duration_s: float
    target: Vec3 | None = None
    amplitude: Vec3 = (0.0, 0.0, 0.0)
    frequency_hz: float = 0.0


@dataclass(frozen=True)
class DisturbanceSpec:
    """The external motor acting on the object.

    ``mode = "wrench"``: force/torque profile applied at ``point_m`` (a point of the
    object, given in ``F`` at the initial pose; the force direction is fixed in ``F``).
    ``mode = "drag"``: a motor follows a displacement profile and pulls the point
    through a spring of ``stiffness_N_per_m`` / ``stiffness_Nm_per_rad``.
    In both modes the motor's viscous damping ``damping_Ns_per_m`` /
    ``damping_Nms_per_rad`` acts on the point's velocity (it bounds the slip speed
    under force control, as a real back-driven motor does).
    """

    mode: str = "wrench"
    point_m: Vec2 = (0.0, 0.0)
    segments: tuple[Segment, ...] = ()
    damping_Ns_per_m: float = 200.0
    damping_Nms_per_rad: float = 0.05
    stiffness_N_per_m: float = 2000.0
    stiffness_Nm_per_rad: float = 0.2


@dataclass(frozen=True)
class SupportSpec:
    """Coulomb friction of a support under the object (N, N·m); 0 disables it."""

    force_N: float = 0.0
    torque_Nm: float = 0.0


@dataclass(frozen=True)
class FtSpec:
    """6-axis F/T sensor model (lib/rig/sensors.py).

    Plausible defaults after the ATI Nano17 with the SI-25-0.25 calibration as listed
    on ATI's public product page (ranges ±25 N in x/y, ±35 N in z, ±250 N·mm; resolution
    1/160 N and 1/32 N·mm). The noise figures are our assumption (≈ 1–2 LSB), not a
    datasheet value. The sensor origin sits ``origin_m`` in ``F`` (20 mm behind the
    pad by default), its axes rotated by ``yaw_rad`` about ``z``.
    """

    enabled: bool = True
    rate_hz: float = 1000.0
    origin_m: Vec3 = (0.0, 0.0, -0.02)
    yaw_rad: float = 0.0
    noise_force_N: float = 0.01
    noise_torque_Nm: float = 5e-5
    bias_force_N: Vec3 = (0.0, 0.0, 0.0)
    bias_torque_Nm: Vec3 = (0.0, 0.0, 0.0)
    resolution_force_N: float = 1.0 / 160.0
    resolution_torque_Nm: float = 1.0 / 32000.0
    range_force_N: Vec3 = (25.0, 25.0, 35.0)
    range_torque_Nm: Vec3 = (0.25, 0.25, 0.25)


@dataclass(frozen=True)
class TactileSpec:
    """Tactile pad model (lib/rig/sensors.py): 12-bit counts per taxel.

    ``counts = baseline + full_scale·(1 − exp(−g_i·p/p0_Pa)) + noise`` with ``p`` the
    mean pressure on the taxel (Pa), ``g_i = 1 + gain_spread·N(0,1)``. Neighbour
    leakage ``crosstalk`` adds that fraction of the 4 neighbours' pressure. Dead
    taxels read 0: the listed ``[row, col]`` pairs plus a random ``dead_fraction``.
    The rubber curve is an empirical saturating fit typical of conductive rubber
    (no datasheet: the paper's Delft sensor has none public); ``p0_Pa = 1e5`` puts
    the 12-bit range over 0–~300 kPa.
    """

    enabled: bool = True
    rate_hz: float = 500.0
    p0_Pa: float = 1e5
    full_scale_counts: int = 4095
    baseline_counts: float = 0.0
    gain_spread: float = 0.05
    noise_counts: float = 4.0
    dead_taxels: tuple[tuple[int, int], ...] = ()
    dead_fraction: float = 0.0
    crosstalk: float = 0.0


@dataclass(frozen=True)
class SimSpec:
    """Integration: internal step ``step_us`` (µs), truth sample rate (Hz)."""

    step_us: int = 1000
    truth_rate_hz: float = 1000.0


@dataclass(frozen=True)
class ExpectSpec:
    """What a scene is meant to show (checked by tests/bench/bench_rig.py --check).

    Attributes:
        slips_at_initial: gross slip occurs when the grip stays at ``f_initial_N``.
        holds_at_N: a fixed grip force (N) at which no gross slip occurs, or None.
    """

    slips_at_initial: bool = True
    holds_at_N: float | None = None


@dataclass(frozen=True)
class MassStep:
    """Mass added to the object at its centre of mass: ``mass_kg`` (kg) from ``at_s`` (s), at
    a steady rate over ``over_s`` (s; 0: at once)."""

    at_s: float
    mass_kg: float
    over_s: float = 0.0

    def added(self, t_s: float) -> float:
        """The mass this step has added by ``t_s`` (kg)."""
        if t_s < self.at_s:
            return 0.0
        if self.over_s <= 0.0 or t_s >= self.at_s + self.over_s:
            return self.mass_kg
        return self.mass_kg * (t_s - self.at_s) / self.over_s


@dataclass(frozen=True)
class GripperSpec:
    """A parallel gripper: finger 1 presses the object's opposite face with the same squeeze.

    Finger 0 is the pad of the scene (``[contact]``, frame ``F``); finger 1's pad frame is
    ``F`` turned by 180° about ``y`` (``x → −x``, ``z → −z``), its contact ``contact`` given
    in that frame (docs/math.md §9). ``gravity_m_s2`` acts on the object's centre of mass,
    in ``F``; a support (the table) carries the whole weight until ``weight_on_s[0]`` and
    none from ``weight_on_s[1]``, linearly between (a pick-up). ``added_mass`` steps add
    mass at the centre of mass (the moment of inertia grows in proportion).
    """

    contact: ContactSpec
    gravity_m_s2: Vec2 = (0.0, -9.81)
    weight_on_s: Vec2 = (0.0, 0.0)
    added_mass: tuple[MassStep, ...] = ()


@dataclass(frozen=True)
class Scene:
    """A whole simulated experiment; build with :func:`load_scene` or :func:`parse_scene`."""

    name: str
    object: ObjectSpec
    contact: ContactSpec
    dof: DofSpec
    disturbance: DisturbanceSpec
    description: str = ""
    seed: int = 0
    duration_s: float = 10.0
    pad: PadGeometry = field(default_factory=PadGeometry)
    finger: FingerSpec = field(default_factory=FingerSpec)
    support: SupportSpec = field(default_factory=SupportSpec)
    ft: FtSpec = field(default_factory=FtSpec)
    tactile: TactileSpec = field(default_factory=TactileSpec)
    sim: SimSpec = field(default_factory=SimSpec)
    expect: ExpectSpec = field(default_factory=ExpectSpec)
    gripper: GripperSpec | None = None

    @property
    def fingers(self) -> int:
        """Fingers pressing the object: 1 (the paper's rig) or 2 (a parallel gripper)."""
        return 1 if self.gripper is None else 2


# ----------------------------------------------------------------------------- loader

def _object(t: ConfigTable) -> ObjectSpec:
    d = ObjectSpec()
    spec = ObjectSpec(
        mass_kg=t.real("mass_kg", d.mass_kg, lo=0.0, lo_open=True),
        inertia_kgm2=t.real("inertia_kgm2", d.inertia_kgm2, lo=0.0, lo_open=True),
        pose=t.vector("pose", 3, d.pose),
    )
    t.finish()
    return spec


def _contact(t: ConfigTable, base: ContactSpec | None = None) -> ContactSpec:
    """A ``[contact]`` table; keys it leaves out come from ``base`` (``model`` is required without one)."""
    d = base or ContactSpec()
    model = t.text("model", REQUIRED if base is None else base.model, choices=PRESSURE_MODELS)
    named = t.has("material")
    material = RIG_MATERIALS[t.text("material", "rubber", choices=tuple(RIG_MATERIALS))]
    mu_s = t.real("mu_s", material[0] if named or base is None else d.mu_s, lo=0.0, lo_open=True)
    mu_d = t.real("mu_d", min(material[1] if named or base is None else d.mu_d, mu_s), lo=0.0, lo_open=True)
    if mu_d > mu_s:
        raise t.error("mu_d", f"must be <= {t.key('mu_s')} ({mu_s}), got {mu_d}")
    spec = ContactSpec(
        model=model,
        mu_s=mu_s,
        mu_d=mu_d,
        mu_spread=t.real("mu_spread", d.mu_spread, lo=0.0, hi=0.3),
        slip_weakening_m=t.real("slip_weakening_m", d.slip_weakening_m, lo=0.0, lo_open=True),
        stiffness_N_per_m3=t.real("stiffness_N_per_m3", d.stiffness_N_per_m3, lo=0.0, lo_open=True),
        damping_Ns_per_m3=t.real("damping_Ns_per_m3", d.damping_Ns_per_m3, lo=0.0),
        stick_speed_m_s=t.real("stick_speed_m_s", d.stick_speed_m_s, lo=0.0, lo_open=True),
        regularisation_speed_m_s=t.real(
            "regularisation_speed_m_s", d.regularisation_speed_m_s, lo=0.0, lo_open=True),
        subsamples=t.integer("subsamples", d.subsamples, lo=1, hi=MAX_SUBSAMPLES),
        moves_with_object=t.flag("moves_with_object", d.moves_with_object),
        footprint=t.text("footprint", d.footprint, choices=("pad", "disc", "rect")),
        centre_m=t.vector("centre_m", 2, d.centre_m),
        radius_m=t.real("radius_m", d.radius_m, lo=0.0, lo_open=True),
        half_size_m=t.vector("half_size_m", 2, d.half_size_m, lo=0.0),
        slope_per_m=t.vector("slope_per_m", 2, d.slope_per_m),
        a_ref_m=t.real("a_ref_m", d.a_ref_m, lo=0.0, lo_open=True),
        b_ref_m=t.real("b_ref_m", d.b_ref_m, lo=0.0, lo_open=True),
        f_ref_N=t.real("f_ref_N", d.f_ref_N, lo=0.0, lo_open=True),
        length_m=t.real("length_m", d.length_m, lo=0.0, lo_open=True),
        angle_rad=t.real("angle_rad", d.angle_rad),
        ridge_depth=t.real("ridge_depth", d.ridge_depth, lo=0.0, hi=1.0),
        ridge_period_m=t.real("ridge_period_m", d.ridge_period_m, lo=0.0, lo_open=True),
        ridge_angle_rad=t.real("ridge_angle_rad", d.ridge_angle_rad),
    )
    if spec.ridge_depth > 0.0 and model not in ("flat", "offset"):
        raise t.error("ridge_depth", f"ridges are a flat or offset face's; the {model} model has none")
    t.finish()
    return spec


def mirrored_contact(spec: ContactSpec) -> ContactSpec:
    """``spec`` seen from the object's opposite face, in finger 1's pad frame (``x → −x``):
    the same footprint, slope and edge mirrored."""
    return replace(spec, centre_m=(-spec.centre_m[0], spec.centre_m[1]),
                   slope_per_m=(-spec.slope_per_m[0], spec.slope_per_m[1]), angle_rad=-spec.angle_rad,
                   ridge_angle_rad=math.pi - spec.ridge_angle_rad)


_SHARED_BRISTLE = ("stiffness_N_per_m3", "damping_Ns_per_m3", "slip_weakening_m", "stick_speed_m_s",
                   "regularisation_speed_m_s")
"""Bristle parameters both fingers of a gripper share (one field of bristles, lib/rig/friction.py)."""


def _gripper(t: ConfigTable, finger0: ContactSpec) -> GripperSpec:
    contact = _contact(t.table("contact"), mirrored_contact(finger0))
    for name in _SHARED_BRISTLE:
        if getattr(contact, name) != getattr(finger0, name):
            raise t.error("contact", f"{name} must equal [contact]'s ({getattr(finger0, name)!r}): both "
                                     f"fingers share one bristle model; give only friction and pressure keys here")
    raw = t.raw("added_mass", [])
    if not isinstance(raw, list):
        raise t.error("added_mass", "must be an array of tables [[gripper.added_mass]]")
    steps = []
    for i, item in enumerate(raw):
        step_t = t.child(item, f"added_mass[{i}]")
        steps.append(MassStep(at_s=step_t.real("at_s", lo=0.0), mass_kg=step_t.real("mass_kg", lo=0.0, lo_open=True),
                              over_s=step_t.real("over_s", 0.0, lo=0.0)))
        step_t.finish()
    weight_on = t.vector("weight_on_s", 2, (0.0, 0.0), lo=0.0)
    if weight_on[1] < weight_on[0]:
        raise t.error("weight_on_s", f"must be [start, end] with end >= start, got {list(weight_on)}")
    spec = GripperSpec(contact=contact, gravity_m_s2=t.vector("gravity_m_s2", 2, (0.0, -9.81)),
                       weight_on_s=weight_on, added_mass=tuple(sorted(steps, key=lambda m: m.at_s)))
    t.finish()
    return spec


def _dof(t: ConfigTable) -> DofSpec:
    free = t.raw("free")
    if (not isinstance(free, list) or not free or len(set(free)) != len(free)
            or any(f not in DOF_NAMES for f in free)):
        raise t.error("free", f"must be a non-empty list of distinct names from {list(DOF_NAMES)}, "
                              f"got {free!r}")
    pivot = t.vector("pivot_m", 2, None)
    ordered = tuple(n for n in DOF_NAMES if n in free)
    if pivot is not None and ordered != ("theta",):
        raise t.error("pivot_m", 'a pivot needs free = ["theta"] (rotation about a fixed axis)')
    t.finish()
    return DofSpec(free=ordered, pivot_m=pivot)


def _finger(t: ConfigTable) -> FingerSpec:
    d = FingerSpec()
    f_max = t.real("f_max_N", d.f_max_N, lo=0.0, lo_open=True)
    spec = FingerSpec(
        f_initial_N=t.real("f_initial_N", d.f_initial_N, lo=0.0, hi=f_max),
        bandwidth_hz=t.real("bandwidth_hz", d.bandwidth_hz, lo=0.0, lo_open=True),
        rate_N_per_s=t.real("rate_N_per_s", d.rate_N_per_s, lo=0.0, lo_open=True),
        f_max_N=f_max,
    )
    t.finish()
    return spec


_CHANNELS = {"wrench": (("force_N", 2), ("torque_Nm", 1)), "drag": (("position_m", 2), ("angle_rad", 1))}


def _channels(t: ConfigTable, mode: str, prefix: str) -> Vec3 | None:
    """Read the three channels of ``mode`` from keys ``prefix + name``; None if absent."""
    (lin, _), (rot, _) = _CHANNELS[mode]
    if not t.has(prefix + lin) and not t.has(prefix + rot):
        return None
    xy = t.vector(prefix + lin, 2, (0.0, 0.0))
    return (xy[0], xy[1], t.real(prefix + rot, 0.0))


def _segment(t: ConfigTable, mode: str) -> Segment:
    kind = t.text("kind", choices=SEGMENT_KINDS)
    duration = t.real("duration_s", lo=0.0)
    target = _channels(t, mode, "")
    if kind in ("step", "ramp") and target is None:
        (lin, _), (rot, _) = _CHANNELS[mode]
        raise t.error("kind", f"a {kind} needs a target: {lin} and/or {rot} (mode {mode!r})")
    if kind in ("hold", "sine") and target is not None:
        raise t.error("kind", f"a {kind} segment takes no target value")
    amplitude = _channels(t, mode, "amplitude_") if kind == "sine" else None
    frequency = t.real("frequency_hz", 0.0 if kind != "sine" else REQUIRED, lo=0.0)
    t.finish()
    return Segment(kind=kind, duration_s=duration, target=target,
                   amplitude=amplitude or (0.0, 0.0, 0.0), frequency_hz=frequency)


def _disturbance(t: ConfigTable) -> DisturbanceSpec:
    d = DisturbanceSpec()
    mode = t.text("mode", d.mode, choices=tuple(_CHANNELS))
    raw = t.raw("segments", [])
    if not isinstance(raw, list):
        raise t.error("segments", "must be an array of tables [[disturbance.segments]]")
    segments = tuple(
        _segment(t.child(s, f"segments[{i}]"), mode) for i, s in enumerate(raw)
    )
    spec = DisturbanceSpec(
        mode=mode,
        point_m=t.vector("point_m", 2, d.point_m),
        segments=segments,
        damping_Ns_per_m=t.real("damping_Ns_per_m", d.damping_Ns_per_m, lo=0.0),
        damping_Nms_per_rad=t.real("damping_Nms_per_rad", d.damping_Nms_per_rad, lo=0.0),
        stiffness_N_per_m=t.real("stiffness_N_per_m", d.stiffness_N_per_m, lo=0.0, lo_open=True),
        stiffness_Nm_per_rad=t.real("stiffness_Nm_per_rad", d.stiffness_Nm_per_rad, lo=0.0,
                                    lo_open=True),
    )
    t.finish()
    return spec


def _simple(t: ConfigTable, cls: type, readers: dict[str, Callable[[ConfigTable, str, Any], Any]]) -> Any:
    d = cls()
    spec = cls(**{name: read(t, name, getattr(d, name)) for name, read in readers.items()})
    t.finish()
    return spec


def _pos(t: ConfigTable, name: str, default: Any) -> float:
    return t.real(name, default, lo=0.0, lo_open=True)


def _rate(t: ConfigTable, name: str, default: Any) -> float:
    return t.real(name, default, lo=0.0, lo_open=True, hi=MAX_SAMPLE_RATE_HZ)


def _nonneg(t: ConfigTable, name: str, default: Any) -> float:
    return t.real(name, default, lo=0.0)


def _vec3(t: ConfigTable, name: str, default: Any) -> Vec3:
    return t.vector(name, 3, default)


def _flag(t: ConfigTable, name: str, default: Any) -> bool:
    return t.flag(name, default)


def _dead(t: ConfigTable, name: str, default: Any) -> tuple[tuple[int, int], ...]:
    value = t.raw(name, list(default))
    ok = isinstance(value, list) and all(
        isinstance(p, list) and len(p) == 2 and all(isinstance(v, int) and not isinstance(v, bool)
                                                    for v in p) for p in value)
    if not ok:
        raise t.error(name, f"must be a list of [row, col] integer pairs, got {value!r}")
    return tuple((int(r), int(c)) for r, c in value)


def _ft(t: ConfigTable) -> FtSpec:
    return _simple(t, FtSpec, {
        "enabled": _flag, "rate_hz": _rate, "origin_m": _vec3,
        "yaw_rad": lambda t, n, d: t.real(n, d),
        "noise_force_N": _nonneg, "noise_torque_Nm": _nonneg,
        "bias_force_N": _vec3, "bias_torque_Nm": _vec3,
        "resolution_force_N": _nonneg, "resolution_torque_Nm": _nonneg,
        "range_force_N": lambda t, n, d: t.vector(n, 3, d, lo=1e-9),
        "range_torque_Nm": lambda t, n, d: t.vector(n, 3, d, lo=1e-9),
    })


def _tactile(t: ConfigTable) -> TactileSpec:
    return _simple(t, TactileSpec, {
        "enabled": _flag, "rate_hz": _rate, "p0_Pa": _pos,
        "full_scale_counts": lambda t, n, d: t.integer(n, d, lo=1),
        "baseline_counts": _nonneg,
        "gain_spread": lambda t, n, d: t.real(n, d, lo=0.0, hi=0.5),
        "noise_counts": _nonneg, "dead_taxels": _dead,
        "dead_fraction": lambda t, n, d: t.real(n, d, lo=0.0, hi=1.0),
        "crosstalk": lambda t, n, d: t.real(n, d, lo=0.0, hi=0.25),
    })


def _expect(t: ConfigTable) -> ExpectSpec:
    return _simple(t, ExpectSpec, {
        "slips_at_initial": _flag,
        "holds_at_N": lambda t, n, d: t.real(n, d, lo=0.0, lo_open=True),
    })


def with_rig_material(scene: Scene, material: str) -> Scene:
    """``scene`` with its contact (both fingers' on a gripper) made of the rig material ``material``
    (see :data:`RIG_MATERIALS`), everything else unchanged; its name gets ``@material``."""
    if material not in RIG_MATERIALS:
        raise ConfigError(f"unknown rig material {material!r}; known: {', '.join(RIG_MATERIALS)}")
    mu_s, mu_d = RIG_MATERIALS[material]
    gripper = scene.gripper
    if gripper is not None:
        gripper = replace(gripper, contact=replace(gripper.contact, mu_s=mu_s, mu_d=mu_d))
    return replace(scene, name=f"{scene.name}@{material}", contact=replace(scene.contact, mu_s=mu_s, mu_d=mu_d),
                   gripper=gripper)


def parse_scene(data: Mapping[str, Any], *, source: str = "<scene>") -> Scene:
    """Build a :class:`Scene` from a parsed TOML mapping.

    Args:
        data: the mapping (as from ``tomllib.loads``).
        source: a name for error messages (the file name).

    Raises:
        ConfigError: naming the offending key and what is expected.
    """
    top = ConfigTable(data, "", source)
    pad_t = top.table("pad")
    pad = PadGeometry(
        rows=pad_t.integer("rows", 16, lo=1),
        cols=pad_t.integer("cols", 16, lo=1),
        pitch_m=pad_t.real("pitch_m", 1.25e-3, lo=0.0, lo_open=True),
    )
    pad_t.finish()
    sim_t = top.table("sim")
    sim = SimSpec(
        step_us=sim_t.integer("step_us", SimSpec.step_us, lo=1),
        truth_rate_hz=_rate(sim_t, "truth_rate_hz", SimSpec.truth_rate_hz),
    )
    sim_t.finish()
    sensors = top.table("sensors")
    ft = _ft(sensors.table("ft"))
    tactile = _tactile(sensors.table("tactile"))
    sensors.finish()
    for bad in (d for d in tactile.dead_taxels if not (0 <= d[0] < pad.rows and 0 <= d[1] < pad.cols)):
        raise ConfigError(f"{source}: sensors.tactile.dead_taxels: {list(bad)} is outside the "
                          f"{pad.rows}x{pad.cols} pad")
    finger = _finger(top.table("finger"))
    contact = _contact(top.table("contact", required=True))
    gripper = _gripper(top.table("gripper"), contact) if top.has("gripper") else None
    scene = Scene(
        name=top.text("name", Path(source).stem),
        description=top.text("description", ""),
        seed=top.integer("seed", 0, lo=0),
        duration_s=top.real("duration_s", 10.0, lo=0.0, lo_open=True),
        pad=pad,
        object=_object(top.table("object", required=True)),
        contact=contact,
        dof=_dof(top.table("dof", required=True)),
        finger=finger,
        disturbance=_disturbance(top.table("disturbance", required=True)),
        support=_simple(top.table("support"), SupportSpec,
                        {"force_N": _nonneg, "torque_Nm": _nonneg}),
        ft=ft,
        tactile=tactile,
        sim=sim,
        expect=_expect(top.table("expect")),
        gripper=gripper,
    )
    top.finish()
    return scene


def load_scene(path: str | Path) -> Scene:
    """Read and validate a scene TOML file.

    Raises:
        ConfigError: unreadable file, TOML syntax error, or an invalid key (named).
    """
    return parse_scene(read_toml(path, "scene"), source=Path(path).name)
