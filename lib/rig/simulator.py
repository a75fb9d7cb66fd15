"""Lock-step simulator of the paper's rig (Melchiorri 2000, §V, Fig. 8).

A fingertip carrying a 6-axis F/T sensor and a tactile pad presses an object; a
motor disturbs the object. :class:`Simulator` integrates the plant (finger
actuator, pressure model, per-taxel bristle friction, planar body in its free
degrees of freedom, disturbance motor) with a fixed internal step and samples the
sensors and the truth at their own rates. Everything is deterministic given the
scene seed. A scene with ``[gripper]`` is a parallel gripper: a second finger, with its
own sensors, presses the opposite face with the same squeeze, and gravity acts
(docs/math.md §9).

More in docs/modules.md, `lib/rig/simulator.py`.
"""

from __future__ import annotations

import cmath
import math
from dataclasses import dataclass
from typing import Iterator, Union

import numpy as np

from slipstack.lib.errors import ConfigError
from slipstack.lib.rig.actuator import FingerActuator
from slipstack.lib.rig.body import PlanarBody
from slipstack.lib.rig import plant_kernel, pressure_kernels, sensor_kernels
from slipstack.lib.rig.contact import PressureModel
from slipstack.lib.rig.disturbance import DisturbanceMotor
from slipstack.lib.rig.friction import BristleField, friction_coefficients
from slipstack.lib.rig.scene import Scene
from slipstack.lib.rig.sensors import FtSensorModel, TactileSensorModel
from slipstack.lib.samples import FtSample, TactileSample

__all__ = ["Truth", "TaxelState", "Sample", "Simulator", "GROSS_SLIP_FRACTION", "MAX_OMEGA_DT", "MAX_DAMPING_DT",
           "compile_kernels"]

GROSS_SLIP_FRACTION = 0.95
"""Gross slip ⇔ slipping taxels, each at the share of its cap it transmits, account for
at least this share of the frictional dissipation capacity ``Σ φ_i |u_i|``
(``BristleField.slip_share``; for a translation at the cap simply the share of ``f_n``). Taxels near the centre of rotation stick during a gross
rotation (they barely move), so the share never reaches exactly 1 there; below the
threshold the contact is in partial slip (edges slipping, core sticking)."""
MAX_OMEGA_DT = 1.0
"""Accuracy guard: the stiffest contact mode ``ω_c`` must satisfy ``ω_c·dt ≤ 1``."""
MAX_DAMPING_DT = 4.0
"""Stability guard: the fastest contact damping rate ``c ω_c²/k`` times ``dt`` at most (the
mid-point rule's factor ``(1 − x/2)/(1 + x/2)`` stays above −1/3: a contact damped harder
than the step resolves chatters)."""
_COR_MIN_OMEGA = 1e-4
"""Below this rate (rad/s) the motion is reported as a translation: no COR."""
_COR_MAX_DISTANCE = 1.0
"""A COR farther than this (m) from the pad origin is reported as None (translation)."""


@dataclass(frozen=True, slots=True)
class Truth:
    """Ground truth of the object relative to the pad (frame ``F``, SI units).

    Attributes:
        stamp_ns: simulated time (ns).
        x, y, theta: pose of the object's centre of mass (m, m, rad).
        vx, vy, omega: its velocity (m/s) and angular rate (rad/s).
        gross_slip: ``slip_fraction ≥ GROSS_SLIP_FRACTION`` (with no contact: the
            object moves).
        slip_fraction: share of the friction capacity in use by slipping taxels
            (``BristleField.slip_share``); 0 < share < 0.95 is partial slip.
        cor: instantaneous centre of rotation ``(x, y)`` (m), None for a translation
            or rest (|ω| < 1e-4 rad/s or farther than 1 m).
        slip_distance_m: path length of the object point over the pad origin,
            accumulated while in gross slip.
        slip_angle_rad: object rotation accumulated while in gross slip (signed).
        slip_direction_rad: direction of the slip velocity at the pad origin while
            in gross slip, else None.
        f_n_applied, f_n_command: applied and commanded normal force (N).
        load_force: tangential load on the object transmitted by the contact
            ``−Σ q_i`` (N); what an ideal F/T reads as ``f_t``.
        load_torque: its torque about ``z`` through the pad origin (N·m).
        disturbance_force, disturbance_torque: the motor's active force (N) at its
            application point and torque (N·m).
        motor_displacement: motor encoder ``(dx m, dy m, dθ rad)`` of the object point.
        energy_J: kinetic plus elastic bristle energy (J).
        work_J: work of the motor's active load (and of gravity) since t = 0 (J).
        finger_loads: on a gripper, per finger ``(f_x N, f_y N, τ N·m)``: the load that
            finger's contact transmits, in the finger's own pad frame (what its ideal F/T
            reads); ``load_force``/``load_torque`` are then both fingers' in ``F``. Empty
            for one finger.
        weight: the object's weight the grasp carries now (N, ``F``; the support's share
            taken off), and mass_kg: its mass (kg).
    """

    stamp_ns: int
    x: float
    y: float
    theta: float
    vx: float
    vy: float
    omega: float
    gross_slip: bool
    slip_fraction: float
    cor: tuple[float, float] | None
    slip_distance_m: float
    slip_angle_rad: float
    slip_direction_rad: float | None
    f_n_applied: float
    f_n_command: float
    load_force: tuple[float, float]
    load_torque: float
    disturbance_force: tuple[float, float]
    disturbance_torque: float
    motor_displacement: tuple[float, float, float]
    energy_J: float
    work_J: float
    finger_loads: tuple[tuple[float, float, float], ...] = ()
    weight: tuple[float, float] = (0.0, 0.0)
    mass_kg: float = 0.0


Sample = Union[FtSample, TactileSample, Truth]


@dataclass(frozen=True)
class TaxelState:
    """Per-taxel contact state, row-major, for tests and diagnostics.

    Attributes:
        phi: normal force per taxel (N), shape (N,).
        sliding: taxel in the slip state, shape (N,), bool.
        force: tangential force each patch exerts on the object (N), shape (N, 2).
    """

    phi: np.ndarray
    sliding: np.ndarray
    force: np.ndarray


class _Clock:
    """Sample times ``k·period`` (ns), taken at the first internal step at or after them.

    ``seq`` counts the samples emitted; :meth:`due` returns how many sample times have
    passed since the last call (more than one when the rate exceeds the step rate).
    """

    __slots__ = ("period_ns", "next_ns", "seq")

    def __init__(self, rate_hz: float) -> None:
        self.period_ns = max(1, round(1e9 / rate_hz))
        self.next_ns = 0
        self.seq = 0

    def due(self, t_ns: int) -> int:
        if t_ns < self.next_ns:
            return 0
        n = (t_ns - self.next_ns) // self.period_ns + 1
        self.next_ns += self.period_ns * n
        return n


class _Finger:
    """One finger's contact and sensors. Finger 1 of a gripper faces the other way: its pad
    frame is ``F`` turned by 180° about ``y``, so a planar point ``z`` of ``F`` is ``−z̄`` in it
    (docs/math.md §9)."""

    def __init__(self, index: int, scene: Scene, contact, rngs: tuple[np.random.Generator, ...]) -> None:
        self.index = index
        self.mirrored = index == 1
        pad = scene.pad
        x, y, theta = scene.object.pose
        self.pressure = PressureModel(contact, pad, (-x, y, -theta) if self.mirrored else (x, y, theta))
        rng_ft, rng_tac_init, rng_tac = rngs
        self.ft = FtSensorModel(scene.ft, pad, rng_ft, index)
        self.tactile = TactileSensorModel(scene.tactile, pad, rng_tac_init, rng_tac, index)
        self.taxels = slice(index * pad.n_taxels, (index + 1) * pad.n_taxels)

    def own(self, z: complex) -> complex:
        """A planar point or vector of ``F`` in this finger's pad frame."""
        return -z.conjugate() if self.mirrored else z

    def shape(self, f_n: float, origin: complex, theta: float) -> np.ndarray:
        """The normalised pressure shape on this pad at the object pose (``F``)."""
        if self.mirrored:
            return self.pressure.shape(f_n, -origin.conjugate(), -theta)
        return self.pressure.shape(f_n, origin, theta)


class Simulator:
    """The rig, stepped in lock-step.

    Args:
        scene: the experiment (see :mod:`slipstack.lib.rig.scene`).

    Raises:
        ConfigError: the contact misses the pad, or the internal step is too coarse
            for the contact stiffness (``ω_c·dt > MAX_OMEGA_DT``).
    """

    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        pad = scene.pad
        self.pad = pad
        self.dt_ns = scene.sim.step_us * 1000
        self._dt = self.dt_ns * 1e-9
        self._t_ns = 0
        self._end_ns = round(scene.duration_s * 1e9)
        root = np.random.SeedSequence(scene.seed)
        rng_friction, *rngs = (np.random.default_rng(s) for s in root.spawn(4))
        p = pad.positions[:, 0] + 1j * pad.positions[:, 1]
        self._fingers = [_Finger(0, scene, scene.contact, tuple(rngs))]
        self._finger = FingerActuator(scene.finger)
        self._body = PlanarBody(scene.object, scene.dof)
        self._pressure = self._fingers[0].pressure
        self._pressure.check_touches_pad(scene.finger.f_initial_N)
        friction = None
        self._gripper = scene.gripper
        if scene.gripper is not None:  # finger 1: its own draws, after finger 0's (which stay those of one finger)
            rng_friction_1, *rngs_1 = (np.random.default_rng(s) for s in root.spawn(4))
            finger1 = _Finger(1, scene, scene.gripper.contact, tuple(rngs_1))
            finger1.pressure.check_touches_pad(scene.finger.f_initial_N)
            self._fingers.append(finger1)
            mu_0 = friction_coefficients(scene.contact, rng_friction, pad.n_taxels)
            mu_1 = friction_coefficients(scene.gripper.contact, rng_friction_1, pad.n_taxels)
            friction = (np.concatenate([mu_0[0], mu_1[0]]), np.concatenate([mu_0[1], mu_1[1]]))
            p = np.concatenate([p, -p.conjugate()])  # finger 1's taxels in F
        self._P = p
        self._bristles = BristleField(scene.contact, pad.taxel_area_m2, self._dt, rng_friction, self._P, friction)
        self._plant_constants = self._bristles.plant_constants(self._body.mass, self._body.inertia,
                                                               self._body.free_mask)
        self._point0 = complex(*scene.disturbance.point_m)
        self._motor = DisturbanceMotor(scene.disturbance, self._point0, self._body.theta)
        self.ft = self._fingers[0].ft
        self.tactile = self._fingers[0].tactile
        self._mass_steps = list(scene.gripper.added_mass) if scene.gripper is not None else []
        self._weight = 0j  # gravity's force on the object now (N, F)
        self._finger_loads: list[tuple[complex, float]] | None = None  # per finger, own frame; of this step
        self._clocks = [
            (kind, _Clock(rate))
            for kind, rate, on in (("ft", scene.ft.rate_hz, scene.ft.enabled),
                                   ("tactile", scene.tactile.rate_hz, scene.tactile.enabled),
                                   ("truth", scene.sim.truth_rate_hz, True))
            if on
        ]
        self._next_due_ns = 0  # the earliest next sample time of the clocks (ns)
        self._shape = None
        self._f_phi = math.nan
        self._contact_load = (0j, 0.0)  # (−Σ q_i N, −Σ p_i × q_i N·m) of the last step
        self._load = self._motor.load(0.0, self._point0, self._body.theta)
        self._motor_damping = self._motor.damping
        self._has_support = scene.support.force_N > 0.0 or scene.support.torque_Nm > 0.0
        self._work = 0.0
        self._slip_distance = 0.0
        self._slip_angle = 0.0
        self._gross = False
        self._slip_fraction = 0.0
        self._shapes: list[np.ndarray | None] = [None] * len(self._fingers)
        self._attached = any(f.pressure.attached for f in self._fingers)
        self._update_pressure(self._finger.force)
        self.contact_mode_rad_s = self._stiffest_mode()
        if self.contact_mode_rad_s * self._dt > MAX_OMEGA_DT:
            limit_us = int(MAX_OMEGA_DT / self.contact_mode_rad_s * 1e6)
            raise ConfigError(
                f"sim.step_us: {scene.sim.step_us} us is too coarse for the contact stiffness "
                f"(stiffest mode {self.contact_mode_rad_s:.0f} rad/s, ω·dt = "
                f"{self.contact_mode_rad_s * self._dt:.2f} > {MAX_OMEGA_DT}); use step_us <= "
                f"{limit_us} or a softer contact.stiffness_N_per_m3")
        # the same geometry damps as it stiffens: the fastest damping rate is c·ω²/k; the mid-point
        # rule multiplies a damped velocity by (1 − x/2)/(1 + x/2) a step, x = rate·dt: beyond
        # MAX_DAMPING_DT it flips sign and barely decays (the contact chatters)
        damping_rate = self._bristles.c * self.contact_mode_rad_s ** 2 / self._bristles.k
        if damping_rate * self._dt > MAX_DAMPING_DT:
            raise ConfigError(
                f"contact.damping_Ns_per_m3: {scene.contact.damping_Ns_per_m3:g} damps the object faster than "
                f"the step resolves ({damping_rate:.0f} 1/s, rate·dt = {damping_rate * self._dt:.2f} > "
                f"{MAX_DAMPING_DT:g}: the contact would chatter); use damping_Ns_per_m3 <= "
                f"{scene.contact.damping_Ns_per_m3 * MAX_DAMPING_DT / (damping_rate * self._dt):.3g} or a "
                "shorter sim.step_us")

    # ------------------------------------------------------------------ public API

    @property
    def t_ns(self) -> int:
        """Current simulated time (ns)."""
        return self._t_ns

    @property
    def end_ns(self) -> int:
        """End of the scene, ``duration_s`` in ns."""
        return self._end_ns

    @property
    def done(self) -> bool:
        """True once no further step fits in the scene's duration (a duration between two
        steps ends at the last step before it)."""
        return self._t_ns + self.dt_ns > self._end_ns

    @property
    def rejected_commands(self) -> int:
        """Number of non-finite normal-force commands ignored."""
        return self._finger.rejected

    @property
    def normal_force_applied(self) -> float:
        """The normal force the finger (a gripper: each finger) applies now, N."""
        return self._finger.force

    @property
    def normal_force_command(self) -> float:
        """The finger's present normal-force command, N."""
        return self._finger.command_N

    def command_normal_force(self, f_n_N: float) -> bool:
        """Command the finger's normal force (N); clipped to ``[0, f_max]``.

        Returns False (command ignored, counted) for a non-finite value.
        """
        return self._finger.command(f_n_N)

    def step_until(self, t_ns: int) -> list[Sample]:
        """Advance to the last internal step at or before ``t_ns`` (simulated ns).

        Returns:
            The samples due in the advanced interval, in time order (at one instant:
            F/T, tactile, truth). Samples at t = 0 come with the first call.
        """
        out: list[Sample] = []
        self._emit(out)
        while self._t_ns + self.dt_ns <= t_ns:
            self._step()
            self._emit(out)
        return out

    def samples(self, chunk_ns: int = 10_000_000) -> Iterator[Sample]:
        """Yield every sample of the scene up to ``duration_s``, lock-step."""
        while not self.done:
            yield from self.step_until(min(self._t_ns + chunk_ns, self._end_ns))

    __iter__ = samples

    def taxel_state(self) -> TaxelState:
        """Copies of the per-taxel contact state now (normal force, slip state)."""
        br = self._bristles
        return TaxelState(phi=br.phi.copy(), sliding=br.sliding.copy(),
                          force=np.column_stack([br.q.real, br.q.imag]))

    def truth(self) -> Truth:
        """The ground truth now."""
        body, br = self._body, self._bristles
        ref = body.reference
        omega = body.omega
        cor = None
        if abs(omega) > _COR_MIN_OMEGA:
            c = ref + 1j * body.v_ref / omega
            if abs(c) <= _COR_MAX_DISTANCE:
                cor = (c.real, c.imag)
        v_origin = body.origin_velocity
        direction = cmath.phase(v_origin) if self._gross and v_origin != 0 else None
        point = body.body_point(self._point0)
        v_com = body.com_velocity
        force, torque = self._load
        lf, lt = self._contact_load
        finger_loads: tuple[tuple[float, float, float], ...] = ()
        if self._gripper is not None:
            finger_loads = tuple((f.real, f.imag, tau) for f, tau in self._loads_by_finger())
        return Truth(
            stamp_ns=self._t_ns,
            x=body.origin.real, y=body.origin.imag, theta=body.theta,
            vx=v_com.real, vy=v_com.imag, omega=omega,
            gross_slip=self._gross,
            slip_fraction=self._slip_fraction,
            cor=cor,
            slip_distance_m=self._slip_distance,
            slip_angle_rad=self._slip_angle,
            slip_direction_rad=direction,
            f_n_applied=self._finger.force,
            f_n_command=self._finger.command_N,
            load_force=(lf.real, lf.imag),
            load_torque=lt,
            disturbance_force=(force.real, force.imag),
            disturbance_torque=torque,
            motor_displacement=self._motor.encoder(point, body.theta),
            energy_J=body.kinetic_energy() + br.potential_energy(),
            work_J=self._work,
            finger_loads=finger_loads,
            weight=(self._weight.real, self._weight.imag),
            mass_kg=body.mass,
        )

    # ------------------------------------------------------------------ internals

    def _emit(self, out: list[Sample]) -> None:
        t = self._t_ns
        if t < self._next_due_ns:  # most steps: no sample is due
            return
        for kind, clock in self._clocks:
            n = clock.due(t)
            if not n:
                continue
            if kind == "ft":  # a sensor faster than the step samples the held state n times
                if self._gripper is None:
                    for k in range(n - 1, -1, -1):
                        out.append(self.ft.measure(t - k * clock.period_ns, clock.seq, self._bristles.phi,
                                                   self._f_phi, *self._contact_load))
                        clock.seq += 1
                    continue
                loads = self._loads_by_finger()
                for k in range(n - 1, -1, -1):
                    for finger, load in zip(self._fingers, loads):
                        out.append(finger.ft.measure(t - k * clock.period_ns, clock.seq,
                                                     self._bristles.phi[finger.taxels], self._f_phi, *load))
                    clock.seq += 1
                continue
            seq = clock.seq
            clock.seq += 1
            if kind == "tactile":
                if self._gripper is None:
                    out.append(self.tactile.measure(t, seq, self._bristles.phi))
                else:
                    out.extend(f.tactile.measure(t, seq, self._bristles.phi[f.taxels]) for f in self._fingers)
            else:
                out.append(self.truth())
        self._next_due_ns = min(clock.next_ns for _, clock in self._clocks)

    def _loads_by_finger(self) -> list[tuple[complex, float]]:
        """Each finger's transmitted load of this step, ``(f_t complex N, τ N·m)`` in its own pad
        frame (the negated force and torque its patches exerted on the object)."""
        if self._finger_loads is None:
            loads = []
            for finger in self._fingers:
                f_q, tau_q = self._bristles.load_of(finger.taxels)
                loads.append((-finger.own(f_q), tau_q if finger.mirrored else -tau_q))
            self._finger_loads = loads
        return self._finger_loads

    def _update_pressure(self, f_n: float) -> None:
        body = self._body
        if self._gripper is not None:
            self._update_pressures(f_n)
            return
        if f_n == self._f_phi and not self._pressure.attached:
            return
        shape = self._pressure.shape(f_n, body.origin, body.theta)
        if shape is self._shape and f_n == self._f_phi:
            return
        self._shape = shape
        self._f_phi = f_n
        self._bristles.set_normal_forces(max(f_n, 0.0), shape)

    def _update_pressures(self, f_n: float) -> None:
        """A gripper's two pads: each presses the object with the squeeze ``f_n``. A footprint
        attached to the object follows its slip, not its elastic twist on the pads: a stuck
        rubber patch moves with the face it touches (docs/math.md §9)."""
        fingers = self._fingers
        attached = self._attached
        if f_n == self._f_phi and not attached:
            return
        body = self._body
        origin, theta = body.origin, body.theta
        if attached:
            t, omega = self._bristles.elastic_twist()
            origin, theta = origin - (t + 1j * omega * origin), theta - omega
        shapes = [f.shape(f_n, origin, theta) for f in fingers]
        if f_n == self._f_phi and all(a is b for a, b in zip(shapes, self._shapes)):
            return
        self._shapes = shapes
        self._f_phi = f_n
        self._bristles.set_normal_forces(max(f_n, 0.0), np.concatenate(shapes))

    def _step(self) -> None:
        """One internal step: the finger and the pressure in Python, then the bristles
        and the body in one compiled call (lib/rig/plant_kernel.py), then the books."""
        dt = self._dt
        body = self._body
        self._update_pressure(self._finger.step(dt))
        point = body.body_point(self._point0)
        force, torque = self._motor.load(self._t_ns * 1e-9, point, body.theta)
        self._load = (force, torque)
        c, s_rot = self._motor_damping
        s, sp, spp = c, c * point, c * (point.real * point.real + point.imag * point.imag)
        if self._has_support:
            s, sp, spp, s_rot = self._support(s, sp, spp, s_rot)
        ref = body.reference
        force_ext, tau_ext = force, (point.conjugate() * force).imag + torque
        if self._gripper is not None:
            weight = self._gravity()
            force_ext += weight
            tau_ext += (body.origin.conjugate() * weight).imag
            self._finger_loads = None
        v_mid, w_mid, f_q, tau_q = self._bristles.step(
            self._plant_constants, ref, body.v_ref, body.omega, s, sp, spp, s_rot, force_ext, tau_ext)
        self._contact_load = (-f_q, -tau_q)
        v0_mid = v_mid - 1j * w_mid * ref  # mid velocity at the pad origin
        v_point = v0_mid + 1j * w_mid * point
        self._work += dt * ((force.conjugate() * v_point).real + torque * w_mid)
        if self._gripper is not None:  # gravity's work, at the centre of mass
            self._work += dt * (self._weight.conjugate() * (v0_mid + 1j * w_mid * body.origin)).real
        body.commit(dt, v_mid, w_mid)
        self._t_ns += self.dt_ns
        self._track_slip(dt, v0_mid, w_mid)

    def _gravity(self) -> complex:
        """Gravity's force on the object now (complex N, ``F``): the mass added so far, the
        share of the weight the support no longer carries (docs/math.md §9)."""
        gripper, body = self._gripper, self._body
        t = self._t_ns * 1e-9
        if self._mass_steps:
            mass = self.scene.object.mass_kg + sum(step.added(t) for step in self._mass_steps)
            if mass != body.mass:
                body.inertia *= mass / body.mass
                body.mass = mass
                self._plant_constants = self._bristles.plant_constants(body.mass, body.inertia, body.free_mask)
        start, end = gripper.weight_on_s
        share = 1.0 if t >= end else 0.0 if t <= start else (t - start) / (end - start)
        self._weight = share * body.mass * complex(*gripper.gravity_m_s2)
        return self._weight

    def _support(self, s: float, sp: complex, spp: float,
                 s_rot: float) -> tuple[float, complex, float, float]:
        """Add Coulomb support friction, linearised like the slipping taxels (dissipative)."""
        support = self.scene.support
        body = self._body
        reg = self.scene.contact.regularisation_speed_m_s
        if support.force_N > 0.0:
            c = support.force_N / max(abs(body.com_velocity), reg)
            o = body.origin
            s, sp, spp = s + c, sp + c * o, spp + c * (o.real**2 + o.imag**2)
        if support.torque_Nm > 0.0:
            s_rot += support.torque_Nm / max(abs(body.omega), reg)
        return s, sp, spp, s_rot

    def _track_slip(self, dt: float, v0_mid: complex, w_mid: float) -> None:
        br = self._bristles
        if self._f_phi > 0.0:
            self._slip_fraction = br.slip_share
            self._gross = self._slip_fraction >= GROSS_SLIP_FRACTION
        else:
            self._slip_fraction = 0.0
            self._gross = abs(self._body.v_ref) + abs(self._body.omega) > 0.0
        if self._gross:
            self._slip_distance += dt * abs(v0_mid)
            self._slip_angle += dt * w_mid

    def _stiffest_mode(self) -> float:
        """Highest natural frequency (rad/s) of the body on a fully stuck, fully
        pressed pad (an upper bound over contact shapes), free coordinates only. A
        gripper's two pads count the taxels their footprints cover at ``f_max`` (a small
        footprint on two whole pads would demand a step far shorter than it needs)."""
        body = self._body
        k = self._bristles.k
        d = self._P - body.reference
        if self._gripper is not None:
            f_max = self.scene.finger.f_max_N
            x, y, theta = self.scene.object.pose
            pressed = np.concatenate([f.shape(f_max, complex(x, y), theta) > 0 for f in self._fingers])
            d = d[pressed]
        K = k * np.array([
            [d.size, 0.0, -d.imag.sum()],
            [0.0, d.size, d.real.sum()],
            [-d.imag.sum(), d.real.sum(), float((d * d.conj()).real.sum())],
        ])
        # M is diagonal: the generalised problem K x = λ M x is the symmetric one of
        # M^{-1/2} K M^{-1/2} (no scipy: its import alone cost 0.15 s of start-up)
        idx = np.array(body.free)
        scale = 1.0 / np.sqrt(np.array([body.mass, body.mass, body.inertia])[idx])
        eig = np.linalg.eigvalsh(K[np.ix_(idx, idx)] * np.outer(scale, scale))
        return float(math.sqrt(max(eig.max(), 0.0)))


def compile_kernels() -> None:
    """Compile the rig's numba kernels (plant step, pressure, sensors), or load them from the cache.

    The rig node calls it in ``start``, so no scene pays it on its first slip or
    Hertzian re-shape; ``make`` and the test suite call it once after install.
    """
    plant_kernel.compile_kernels()
    pressure_kernels.compile_kernels()
    sensor_kernels.compile_kernels()
