"""A second, independent contact world on MuJoCo, written as slipstack recordings.

A rigid object pressed on a fingertip of 256 point contacts (lib/pad.py's grid) with
Coulomb friction (μ_s = μ_d, elliptic cones); loads ramped past slip and held under it,
as a user records them. The rig's sensor models and the drivers' arithmetic turn the
contact into ``ft/wrench`` and ``tactile/frame``; ``rig/truth`` comes from the object's
motion. Model, thresholds and their reasons: docs/engine_mujoco.md.

    python tests/bench/engine_mujoco.py --out DIR [--scenarios NAME...] [--ft-rate HZ --tactile-rate HZ]
    python tests/bench/engine_mujoco.py --validate      # the engine against analytic limits
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

try:
    import mujoco
except ImportError:  # a bench extra, not a run-time dependency
    sys.exit("engine_mujoco needs MuJoCo: pip install -e '.[bench]' (or pip install mujoco)")

from slipstack.lib.calibration import Calibration
from slipstack.lib.fusion import wrench_to_pad
from slipstack.lib.limit_set import load_factor, torsional_coefficient
from slipstack.lib.pad import PadGeometry
from slipstack.lib.rig.scene import FingerSpec, FtSpec, TactileSpec
from slipstack.lib.rig.sensors import FtSensorModel, TactileSensorModel
from slipstack.messages import Header, RigTruth, TactileFrame, Wrench, encode
from slipstack.nodes.recording.bag_io import RecordingWriter, claim_recording_path

PAD = PadGeometry()
STEP_S = 5e-4
"""Integration step (s): two steps per truth sample."""
SAMPLE_NS = 1_000_000
"""State and truth period (ns): 1 kHz."""
TAXEL_STIFFNESS_N_PER_M = 65.0
"""Normal stiffness of one contact (Winkler pad): 5 N press a flat pad 0.30 mm."""
IMPEDANCE = 0.004
"""MuJoCo constraint impedance of the contacts: low, so a contact acts as a spring (docs)."""
IMPRATIO = 1e6
"""Friction-to-normal impedance ratio: a sticking object creeps at 1.2e-7 m/s at most (docs)."""
SOLVER_TOLERANCE = 1e-14
"""Newton's stopping tolerance: at MuJoCo's 1e-8 it stopped short while the pad was partly
at the cone and the object drifted at 6e-5 m/s under a pure torque at 0.75 of its limit."""
SPHERE_RADIUS_M = 2e-3
OBJECT_MASS_KG = 0.2
OBJECT_HALF_SIZE_M = (0.03, 0.03, 0.005)
MOTOR_DAMPING = (200.0, 0.05)
"""Back-driven damping of the load motor, N·s/m and N·m·s/rad (the rig's DisturbanceSpec)."""
SLIP_ON_M_S = 1e-5
"""Gross slip: the mean slip speed Σφ|u|/Σφ exceeds this (m/s) ..."""
SLIP_OFF_M_S = 1e-6
"""... and the episode spans the samples around it above this (m/s)."""
STICK_GUARD_NS = 20_000_000
"""Samples this close to an episode are left out of the creep figure (ns)."""
AT_CONE = 1e-3
"""A contact slides when its friction force is within this share of μ·φ (sliding_fraction)."""
FT_OFFSET_M = (0.0, 0.0, -0.02)
"""The F/T sensor origin in the pad frame (the stack's ft_driver pad_offset_m)."""


@dataclass(frozen=True)
class PadShape:
    """The fingertip's surface: heights of the 256 contact points (m, 0 at the highest)."""

    name: str
    radius_m: float = 0.0
    tilt_rad: float = 0.0

    def heights(self) -> np.ndarray:
        x, y = PAD.positions.T
        h = np.zeros(PAD.n_taxels)
        if self.radius_m > 0:
            h = -(x * x + y * y) / (2.0 * self.radius_m)
        h = h + math.tan(self.tilt_rad) * x
        return h - h.max()


PADS = {"flat": PadShape("flat"), "curved": PadShape("curved", radius_m=0.02),
        "tilted": PadShape("tilted", tilt_rad=math.radians(0.6))}


@dataclass(frozen=True)
class Scenario:
    """One recording: load ``λ(t)·L·direction`` and normal force command ``f_n(t)``.

    ``L`` scales the direction ``(f_x N, f_y N, τ N·m)`` to the contact's limit at the
    moment the load starts (lib/limit_set.py on the engine's own normal forces; about
    the pivot with ``pivot_m``). Knots ``(t s, value)`` are joined linearly.
    """

    name: str
    description: str
    pad: str
    mu: float
    direction: tuple[float, float, float]
    load: tuple[tuple[float, float], ...]
    normal: tuple[tuple[float, float], ...]
    pivot_m: tuple[float, float] | None = None
    expect_slip: bool = True
    start_s: float = 0.0
    """The recording starts here (the finger pressed before it, off the record)."""

    @property
    def duration_s(self) -> float:
        """Length of the recording, s."""
        return max(self.load[-1][0], self.normal[-1][0]) - self.start_s


def _session(peaks: tuple[float, ...], *, f_n: float = 5.0, ramp_s: float = 1.5, hold_s: float = 0.5,
             unload_s: float = 0.3, rest_s: float = 0.6) -> tuple[tuple, tuple]:
    """Knots of a user's session: press, settle, then per peak ramp, hold, unload, rest."""
    t = 0.6
    load = [(0.0, 0.0), (t, 0.0)]
    for peak in peaks:
        load += [(t + ramp_s, peak), (t + ramp_s + hold_s, peak), (t + ramp_s + hold_s + unload_s, 0.0),
                 (t + ramp_s + hold_s + unload_s + rest_s, 0.0)]
        t = load[-1][0]
    return tuple(load), ((0.0, 0.0), (0.3, f_n), (t, f_n))


def _normal_step(low: float) -> tuple[tuple, tuple]:
    """Load to 0.7 of the 5 N limit, then the grip steps to ``low`` N and back."""
    load = ((0.0, 0.0), (0.6, 0.0), (1.1, 0.7), (2.4, 0.7), (2.7, 0.0), (3.3, 0.0))
    normal = ((0.0, 0.0), (0.3, 5.0), (1.4, 5.0), (1.401, low), (1.8, low), (1.801, 5.0), (3.3, 5.0))
    return load, normal


FORCE = (math.cos(math.radians(30)), math.sin(math.radians(30)), 0.0)
TORQUE = (0.0, 0.0, 1.0)
COMBINED = (1.0, 0.0, 0.004)  # 4 mm lever: neither force nor torque dominates
PIVOT_M = (0.02, 0.0)


def scenarios(mu: float) -> list[Scenario]:
    """The benchmark's scenarios on an object of friction ``mu`` (chosen once, docs)."""
    out = []
    m = f"mu{mu:.2f}"
    slips = _session((1.15, 1.15))
    for pad in PADS:
        for kind, direction in (("force", FORCE), ("torque", TORQUE), ("combined", COMBINED)):
            out.append(Scenario(f"{kind}_{pad}_{m}", f"{kind} ramped past slip twice (press, ramp, hold, unload, "
                                f"rest)", pad, mu, direction, *slips))
    out.append(Scenario(f"pivot_flat_{m}", "torque about a pivot 20 mm off the pad centre, twice past slip",
                        "flat", mu, TORQUE, *slips, pivot_m=PIVOT_M))
    for pad in ("flat", "curved"):
        out.append(Scenario(f"fn_step_{pad}_{m}", "load at 0.7 of the limit, grip steps 5 -> 3 N (slips) and back",
                            pad, mu, FORCE, *_normal_step(3.0)))
        for kind, direction in (("force", FORCE), ("torque", TORQUE), ("combined", COMBINED)):
            out.append(Scenario(f"hold95_{kind}_{pad}_{m}", f"{kind} ramped to 95 % of the limit, held 2 s",
                                pad, mu, direction, *_session((0.95,), hold_s=2.0), expect_slip=False))
    pressed = _session((1.15,), rest_s=0.8)
    for kind, direction in (("force", (1.0, 0.0, 0.0)), ("torque", TORQUE)):
        out.append(Scenario(f"ident_{kind}_flat_{m}", f"{kind} ramp as a user records it: pressed before the record, "
                            "ramp past slip, hold, unload, rest", "flat", mu, direction, *pressed, start_s=0.3))
    out.append(Scenario(f"fn_step_hold_flat_{m}", "load at 0.7 of the limit, grip steps 5 -> 4 N (holds) and back",
                        "flat", mu, FORCE, *_normal_step(4.0), expect_slip=False))
    return out


ALL_SCENARIOS = {s.name: s for mu in (0.5, 0.45) for s in scenarios(mu)}


# -- the contact world --------------------------------------------------------------------

def _model_xml(pad: PadShape, mu: float, pivot_m: tuple[float, float] | None) -> str:
    k_per_mass = TAXEL_STIFFNESS_N_PER_M * (1.0 - IMPEDANCE) / OBJECT_MASS_KG
    stiffness = PAD.n_taxels * TAXEL_STIFFNESS_N_PER_M
    damping = 2.0 * math.sqrt(stiffness * OBJECT_MASS_KG * (1.0 + PAD.n_taxels * IMPEDANCE)) / PAD.n_taxels
    b_per_mass = damping * (1.0 - IMPEDANCE) / OBJECT_MASS_KG
    r = SPHERE_RADIUS_M
    taxels = "\n".join(f'<geom name="taxel{i}" type="sphere" size="{r}" pos="{x!r} {y!r} {z - r!r}"/>'
                       for i, ((x, y), z) in enumerate(zip(PAD.positions.tolist(), pad.heights().tolist())))
    hx, hy, hz = OBJECT_HALF_SIZE_M
    lin, rot = MOTOR_DAMPING
    if pivot_m is None:
        joints = (f'<joint name="x" type="slide" axis="1 0 0" damping="{lin}"/>'
                  f'<joint name="y" type="slide" axis="0 1 0" damping="{lin}"/>'
                  '<joint name="z" type="slide" axis="0 0 1"/>'
                  f'<joint name="theta" type="hinge" axis="0 0 1" damping="{rot}"/>')
    else:
        joints = ('<joint name="z" type="slide" axis="0 0 1"/>'
                  f'<joint name="theta" type="hinge" axis="0 0 1" pos="{pivot_m[0]} {pivot_m[1]} 0" damping="{rot}"/>')
    return f"""<mujoco model="slipstack_fingertip">
  <option timestep="{STEP_S}" gravity="0 0 0" cone="elliptic" impratio="{IMPRATIO}"
          tolerance="{SOLVER_TOLERANCE}" integrator="implicitfast"/>
  <default><geom solref="{-k_per_mass!r} {-b_per_mass!r}" solimp="{IMPEDANCE} {IMPEDANCE} 0.001"
                 friction="{mu} 0 0" condim="3"/></default>
  <worldbody>
    {taxels}
    <body name="object" pos="0 0 {hz}">
      {joints}
      <geom name="object" type="box" size="{hx} {hy} {hz}" mass="{OBJECT_MASS_KG}"/>
    </body>
  </worldbody>
</mujoco>"""


@dataclass
class State:
    """The contact at one sample (pad frame F, SI): per-taxel normal force ``phi`` (N),
    the wrench the object exerts on the pad (``load`` (f_x, f_y) N, ``load_tau`` N·m
    about the origin), the object's pose, velocity and slip quantities."""

    t_ns: int
    phi: np.ndarray
    load: np.ndarray
    load_tau: float
    pose: np.ndarray  # x, y (centre of mass), theta
    velocity: np.ndarray  # vx, vy (centre of mass), omega
    anchor: np.ndarray  # the hinge axis (x, y) and its velocity (vx, vy)
    slip_speed: float  # Σ φ|u| / Σ φ, m/s
    sliding_fraction: float
    f_n_applied: float
    f_n_command: float


class ContactWorld:
    """The MuJoCo model of one scenario, stepped and sampled at 1 kHz."""

    def __init__(self, scenario: Scenario) -> None:
        self.scenario = scenario
        self.model = mujoco.MjModel.from_xml_string(_model_xml(PADS[scenario.pad], scenario.mu, scenario.pivot_m))
        self.data = mujoco.MjData(self.model)
        self.object = self.model.body("object").id
        self.object_geom = self.model.geom("object").id
        self.taxel_geom0 = self.model.geom("taxel0").id
        self.hinge = self.model.joint("theta").id
        self.free = scenario.pivot_m is None
        self.finger = FingerSpec()
        self.f_applied = 0.0
        self.scale = math.nan  # L: the load direction at λ = 1
        self.beta_m = math.nan  # the contact's true β (m) when the load starts
        self._mu = scenario.mu
        self._steps_per_sample = round(SAMPLE_NS * 1e-9 / STEP_S)

    def _interp(self, knots: tuple[tuple[float, float], ...], t: float) -> float:
        ts, vs = zip(*knots)
        return float(np.interp(t, ts, vs))

    def _finger_step(self, command: float) -> None:
        """The rig finger's lag and rate limit (FingerSpec) between command and pressing force."""
        alpha = 1.0 - math.exp(-2.0 * math.pi * self.finger.bandwidth_hz * STEP_S)
        change = alpha * (command - self.f_applied)
        limit = self.finger.rate_N_per_s * STEP_S
        self.f_applied += max(-limit, min(limit, change))

    def contacts(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per taxel: normal force (N), tangential force of the object on the pad (N, (256, 2)),
        and the contact points (m, (256, 2))."""
        d = self.data
        phi = np.zeros(PAD.n_taxels)
        tangential = np.zeros((PAD.n_taxels, 2))
        points = PAD.positions.copy()
        n = d.ncon
        if n:
            c = d.contact
            active = c.efc_address[:n] >= 0  # a contact with no constraint rows carries no force
            geom, addr = c.geom[:n][active], c.efc_address[:n][active]
            taxel = np.where(geom[:, 0] == self.object_geom, geom[:, 1], geom[:, 0]) - self.taxel_geom0
            on_object = np.where(geom[:, 1] == self.object_geom, 1.0, -1.0)  # force on geom2 = frameᵀ f
            f = np.stack([d.efc_force[addr], d.efc_force[addr + 1], d.efc_force[addr + 2]], axis=1)
            frame = c.frame[:n][active].reshape(-1, 3, 3)
            world = np.einsum("nk,nkj->nj", f, frame) * on_object[:, None]  # force on the object
            phi[taxel] = world[:, 2]
            tangential[taxel] = -world[:, :2]  # the object's force on the pad
            points[taxel] = c.pos[:n][active][:, :2]
        return phi, tangential, points

    def _limit_scale(self, phi: np.ndarray) -> float:
        fx, fy, tau = self.scenario.direction
        if self.scenario.pivot_m is not None:
            arm = np.hypot(*(PAD.positions - np.asarray(self.scenario.pivot_m)).T)
            return self._mu * float(phi @ arm) / abs(tau)
        r = load_factor(phi, PAD.positions, np.array([fx, fy]), tau, self._mu)
        return 1.0 / r.gamma

    def state(self, t_ns: int, command: float) -> State:
        """The contact and the object's motion now (``command``: the grip's command, N)."""
        d = self.data
        phi, tangential, points = self.contacts()
        anchor = d.xanchor[self.hinge][:2].copy()
        qv = d.qvel
        omega = float(qv[self.model.jnt_dofadr[self.hinge]])
        v_anchor = np.array([qv[0], qv[1]]) if self.free else np.zeros(2)
        com = d.xipos[self.object][:2].copy()
        rel = points - anchor
        u = v_anchor + omega * np.column_stack([-rel[:, 1], rel[:, 0]])
        speed = np.hypot(u[:, 0], u[:, 1])
        f_n = float(phi.sum())
        slip_speed = float(phi @ speed) / f_n if f_n > 0 else 0.0
        at_cone = np.hypot(tangential[:, 0], tangential[:, 1]) >= (1.0 - AT_CONE) * self._mu * phi
        at_cone &= phi > 0
        weights = phi * speed
        total = weights.sum()
        if total > 0:  # the rig's share: Σ_sliding φ|u| / Σ φ|u|; at rest the share of f_n
            sliding = float(weights[at_cone].sum() / total)
        else:
            sliding = float(phi[at_cone].sum()) / f_n if f_n > 0 else 0.0
        v_com = v_anchor + omega * np.array([-(com[1] - anchor[1]), com[0] - anchor[0]])
        load_tau = float(np.sum(points[:, 0] * tangential[:, 1] - points[:, 1] * tangential[:, 0]))  # about the origin
        theta = float(d.qpos[self.model.jnt_qposadr[self.hinge]])
        return State(t_ns, phi, tangential.sum(axis=0), load_tau, np.array([*com, theta]), np.array([*v_com, omega]),
                     np.array([*anchor, *v_anchor]), slip_speed, sliding, self.f_applied, command)

    def run(self, progress: Callable[[float], None] | None = None) -> list[State]:
        """Integrate the whole scenario; one :class:`State` per 1 ms from ``start_s`` (then t = 0)."""
        sc, d = self.scenario, self.data
        n_samples = int(round((sc.duration_s + sc.start_s) * 1e9 / SAMPLE_NS))
        states = [self.state(0, 0.0)]
        fx = fy = tau = 0.0
        for k in range(1, n_samples + 1):
            for _ in range(self._steps_per_sample):
                t = d.time
                command = self._interp(sc.normal, t)
                self._finger_step(command)
                lam = self._interp(sc.load, t)
                if lam > 0 and not math.isfinite(self.scale):
                    phi = self.contacts()[0]
                    self.scale = self._limit_scale(phi)
                    self.beta_m = torsional_coefficient(phi, PAD.positions, self._mu).beta_m
                if lam > 0:
                    fx, fy, tau = (lam * self.scale * c for c in sc.direction)
                else:
                    fx = fy = tau = 0.0
                d.xfrc_applied[self.object] = (fx, fy, -self.f_applied, 0.0, 0.0, tau)
                mujoco.mj_step(self.model, d)
            states.append(self.state(k * SAMPLE_NS, command))
            if progress is not None and k % 500 == 0:
                progress(k / n_samples)
        first = round(sc.start_s * 1e9 / SAMPLE_NS)
        for s in states[first:]:
            s.t_ns -= first * SAMPLE_NS
        return states[first:]


# -- truth and sensors ----------------------------------------------------------------------

def gross_slip(speed: np.ndarray) -> np.ndarray:
    """True gross slip per sample: runs above SLIP_OFF_M_S that reach SLIP_ON_M_S."""
    above = speed > SLIP_OFF_M_S
    out = np.zeros(speed.size, dtype=bool)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], above.astype(np.int8), [0]])))
    for start, stop in zip(edges[::2], edges[1::2]):
        if np.any(speed[start:stop] > SLIP_ON_M_S):
            out[start:stop] = True
    return out


def truth_messages(states: list[State]) -> list[RigTruth]:
    """``rig/truth`` with the rig's semantics (messages/types.py RigTruth, lib/rig/simulator.py Truth)."""
    gross = gross_slip(np.array([s.slip_speed for s in states]))
    out, distance, angle = [], 0.0, 0.0
    dt = SAMPLE_NS * 1e-9
    for s, g in zip(states, gross):
        ax, ay, avx, avy = s.anchor
        omega = s.velocity[2]
        v_origin = complex(avx, avy) + 1j * omega * complex(-ax, -ay)  # velocity of the object point at the pad origin
        if g:
            distance += abs(v_origin) * dt
            angle += omega * dt
        cor, valid = np.zeros(2), False
        if abs(omega) > 1e-4:
            c = complex(ax, ay) + 1j * complex(avx, avy) / omega
            if abs(c) <= 1.0:
                cor, valid = np.array([c.real, c.imag]), True
        out.append(RigTruth(x=float(s.pose[0]), y=float(s.pose[1]), theta=float(s.pose[2]), vx=float(s.velocity[0]),
                            vy=float(s.velocity[1]), omega=float(omega), gross_slip=bool(g), cor=cor, cor_valid=valid,
                            slip_distance_m=distance, slip_angle_rad=angle, f_n_applied=s.f_n_applied,
                            f_n_command=s.f_n_command, sliding_fraction=s.sliding_fraction,
                            load_f_t=np.array(s.load, dtype=float), load_tau=s.load_tau))
    return out


@dataclass
class Rates:
    """Sample rates, Hz (1 kHz divided by a whole number; 0: the topic is not recorded)."""

    ft_hz: float = 1000.0
    tactile_hz: float = 1000.0
    truth_hz: float = 1000.0

    def every(self, hz: float) -> int:
        """Samples of the 1 kHz state per recorded sample (0: never)."""
        if hz == 0:
            return 0
        n = 1e9 / hz / SAMPLE_NS if hz > 0 else math.nan
        if not abs(n - round(n)) < 1e-9 or n < 1:
            raise SystemExit(f"a rate of {hz:g} Hz is not 1 kHz divided by a whole number; pick e.g. 1000, 500, "
                             "250, or 0 to leave the topic out")
        return round(n)


def write_recording(path: Path, scenario: Scenario, states: list[State], rates: Rates, seed: int) -> dict:
    """The recording of ``states`` through the rig's sensor models; returns its summary."""
    rng_ft, rng_init, rng_tac = (np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(3))
    ft = FtSensorModel(FtSpec(rate_hz=rates.ft_hz), PAD, rng_ft)
    tactile = TactileSensorModel(TactileSpec(rate_hz=rates.tactile_hz), PAD, rng_init, rng_tac)
    table_pa, table_counts = tactile.calibration_table()  # what the rig writes for the tactile driver
    calibration = Calibration(counts=table_counts, pressure_pa=table_pa,
                              saturation_counts=tactile.spec.full_scale_counts)
    truth = truth_messages(states)
    ft_every, tac_every, truth_every = (rates.every(hz) for hz in (rates.ft_hz, rates.tactile_hz, rates.truth_hz))
    seqs = {"ft/wrench": 0, "tactile/frame": 0, "rig/truth": 0}
    eye, offset = np.eye(3), np.asarray(FT_OFFSET_M)
    with RecordingWriter(path, wall_minus_monotonic_ns=0) as writer:
        def put(topic: str, msg, t_ns: int) -> None:
            writer.write(topic, encode(msg, Header(t_ns, seqs[topic], t_ns, {})), t_ns)
            seqs[topic] += 1

        for k, s in enumerate(states):
            if ft_every and k % ft_every == 0:
                f_n = float(s.phi.sum())
                sample = ft.measure(s.t_ns, seqs["ft/wrench"], s.phi, f_n, complex(*s.load), s.load_tau)
                force, torque = wrench_to_pad(sample.force_n, sample.torque_nm, eye, offset)
                put("ft/wrench", Wrench(force=force, torque=torque, frame="pad", device_seq=sample.device_seq), s.t_ns)
            if tac_every and k % tac_every == 0:
                frame = calibration.apply(tactile.measure(s.t_ns, seqs["tactile/frame"], s.phi).counts.ravel())
                put("tactile/frame", TactileFrame(rows=PAD.rows, cols=PAD.cols, pitch_m=PAD.pitch_m,
                                                  pressure_pa=frame.pressure_pa.astype(np.float32),
                                                  saturated=frame.saturated, dead=frame.dead), s.t_ns)
            if truth_every and k % truth_every == 0:
                put("rig/truth", truth[k], s.t_ns)
    return summarise(scenario, states)


def episodes_of(states: list[State]) -> list[tuple[float, float]]:
    """The true gross-slip episodes (onset s, end s)."""
    gross = gross_slip(np.array([s.slip_speed for s in states]))
    edges = np.flatnonzero(np.diff(np.concatenate([[0], gross.astype(np.int8), [0]])))
    return [(states[a].t_ns / 1e9, states[b - 1].t_ns / 1e9) for a, b in zip(edges[::2], edges[1::2])]


def summarise(scenario: Scenario, states: list[State]) -> dict:
    speed = np.array([s.slip_speed for s in states])
    gross = gross_slip(speed)
    guard = round(STICK_GUARD_NS / SAMPLE_NS)  # the object still accelerating or stopping
    near = np.convolve(gross.astype(float), np.ones(2 * guard + 1), mode="same") > 0
    stick = ~near & np.array([s.f_n_applied > 0.5 for s in states])
    return {"scenario": asdict(scenario), "episodes_s": episodes_of(states),
            "max_stick_slip_speed_m_s": float(speed[stick].max()) if np.any(stick) else 0.0,
            "final_slip_distance_mm": 1e3 * float(np.hypot(*(states[-1].pose[:2] - states[0].pose[:2]))),
            "final_angle_deg": math.degrees(states[-1].pose[2] - states[0].pose[2])}


@dataclass
class Generated:
    path: Path
    summary: dict = field(default_factory=dict)
    cpu_s: float = 0.0


def generate(scenario: Scenario, out: Path, rates: Rates, *, seed: int = 0,
             say: Callable[[str], None] = lambda s: None) -> Generated:
    """Simulate ``scenario`` and write ``out/<name>.mcap`` and its ``.json`` summary."""
    path = out / f"{scenario.name}.mcap"
    if path.exists():
        raise SystemExit(f"{path} exists; delete it or pass another --out")
    claim_recording_path(path)  # a folder that cannot be written fails before the simulation
    t0 = time.process_time()
    world = ContactWorld(scenario)
    states = world.run(lambda f: say(f"{scenario.name}: {100 * f:5.1f} %"))
    t1 = time.process_time()
    summary = write_recording(path, scenario, states, rates, seed)
    summary.update(limit_scale=world.scale, beta_true_m=world.beta_m, **asdict(rates), seed=seed,
                   cpu_s=time.process_time() - t0, simulation_cpu_s=t1 - t0, bytes=path.stat().st_size)
    path.with_suffix(".json").write_text(json.dumps(summary))
    return Generated(path, summary, summary["cpu_s"])


TRUTH_NOTE = ("rig/truth as the rig's (messages/types.py RigTruth): gross_slip from the object's motion "
              f"(mean slip speed over the contacts > {SLIP_ON_M_S:g} m/s, spanning the samples > {SLIP_OFF_M_S:g} "
              "m/s; docs/engine_mujoco.md), slip_distance_m / slip_angle_rad accumulated while in gross slip, "
              "pose and velocity of the object's centre of mass in the pad frame, f_n_applied the finger's force, "
              "load_f_t / load_tau the wrench the object exerts on the pad (what an ideal F/T reads)")


def write_readme(out: Path) -> Path:
    """``out/README.md``: one row per recording in ``out`` (from the ``.json`` summaries)."""
    rows = []
    for path in sorted(out.glob("*.json")):
        s = json.loads(path.read_text())
        sc = s["scenario"]
        unit = "N·m" if sc["direction"][:2] == [0.0, 0.0] else "N"
        values = [v for _, v in sc["load"]]
        peaks = [v for i, v in enumerate(values) if v > 0 and (i == 0 or v != values[i - 1])]
        loads = ", ".join(f"{v:g}" for v in peaks) or "-"
        onsets = ", ".join(f"{a:.3f}–{b:.3f}" for a, b in s["episodes_s"]) or "none (never slips)"
        rates = "/".join(f"{s[k]:g}" for k in ("ft_hz", "tactile_hz", "truth_hz"))
        rows.append(f"| {path.with_suffix('.mcap').name} | {sc['description']} | {sc['mu']:g} | {sc['pad']} | "
                    f"{tuple(sc['direction'])}{' about ' + str(tuple(sc['pivot_m'])) if sc['pivot_m'] else ''}, "
                    f"limit {s['limit_scale']:.4g} {unit}; peaks × limit: {loads} | {onsets} | {rates} | "
                    f"{s['bytes'] / 1e3:.0f} kB |")
    text = "\n".join([
        "# MuJoCo engine recordings", "",
        "Made by `tests/bench/engine_mujoco.py` (branch `mujoco`); the model and its thresholds: "
        "docs/engine_mujoco.md. Coulomb contact, μ_s = μ_d = μ. Times are s from the recording's start; "
        "the load is `peak × limit × direction` (f_x N, f_y N, τ N·m), the limit from the engine's own "
        "normal forces when the load starts (f_n 5 N). Each `.mcap` has a `.json` beside it with the whole "
        "scenario (load and normal-force knots in scenario time, `start_s`), the episodes and the cost.", "",
        f"Truth: {TRUTH_NOTE}.", "",
        "| file | scenario | μ | pad | load direction, limit, peaks | true gross slip (onset–end, s) | "
        "F/T / tactile / truth Hz | size |",
        "| --- | --- | ---: | --- | --- | --- | --- | ---: |", *rows, ""])
    readme = out / "README.md"
    readme.write_text(text)
    return readme


# -- validation against analytic limits ----------------------------------------------------

CHECKS = (("force", "flat", 0.5, (1.0, 0.0, 0.0), None), ("force", "flat", 0.45, (0.0, 1.0, 0.0), None),
          ("torque", "flat", 0.5, TORQUE, None), ("torque", "curved", 0.5, TORQUE, None),
          ("combined", "tilted", 0.45, COMBINED, None), ("force", "curved", 0.45, FORCE, None),
          ("pivot", "flat", 0.5, TORQUE, PIVOT_M))
"""Slow ramps through the predicted limit (kind, pad, μ, direction, pivot)."""
SLOW_RAMP = ((0.0, 0.0), (0.6, 0.0), (0.8, 0.95), (2.8, 1.05), (3.0, 1.05))
"""λ from 0.95 to 1.05 of the predicted limit in 2 s: 5e-5 per 1 ms sample."""


def validate(say: Callable[[str], None]) -> list[str]:
    """Where gross slip begins on slow ramps, against lib/limit_set.py and the analytic limits."""
    grid_mean = float(np.mean(np.hypot(*PAD.positions.T)))
    b = PAD.cols * PAD.pitch_m / 2
    square_mean = b * (math.sqrt(2) + math.log(1 + math.sqrt(2))) / 3
    torque_onset = math.nan
    rows = ["| load | pad | μ | f_n N | limit (lib/limit_set) | analytic | onset λ (engine / limit_set) | "
            "onset / analytic − 1 |", "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for kind, pad, mu, direction, pivot in CHECKS:
        sc = Scenario(f"validate_{kind}_{pad}", "slow ramp", pad, mu, direction, SLOW_RAMP,
                      ((0.0, 0.0), (0.3, 5.0), (3.0, 5.0)), pivot_m=pivot)
        world = ContactWorld(sc)
        states = world.run(lambda f: say(f"validate {kind} {pad} μ {mu}: {100 * f:5.1f} %"))
        eps = episodes_of(states)
        onset = eps[0][0] if eps else math.nan
        lam = float(np.interp(onset, *zip(*SLOW_RAMP)))
        f_n = float(states[round(0.8e9 / SAMPLE_NS)].phi.sum())
        unit = {"force": "N", "combined": "N of f_x (τ = f_x × 4 mm)"}.get(kind, "N·m")
        analytic, error = "-", "-"
        if pad == "flat" and kind in ("force", "torque"):
            value = mu * f_n * (1.0 if kind == "force" else grid_mean)
            analytic = f"{value:.6g} {unit} (μ f_n{'' if kind == 'force' else ' r̄, the grid'})"
            error = f"{100 * (lam * world.scale / value - 1):+.3f} %"
            if kind == "torque":
                torque_onset = lam * world.scale / (mu * f_n)  # the engine's lever arm, m
        rows.append(f"| {kind} | {pad} | {mu:g} | {f_n:.4f} | {world.scale:.6g} {unit} | {analytic} | "
                    f"{lam:.5f} | {error} |")
    note = (f"Pure torque on the flat pad, as a lever arm T/(μ f_n): the continuous uniform square "
            f"b(√2 + ln(1+√2))/3 = {square_mean * 1e3:.4f} mm; the 256-point grid's mean |p_i| = "
            f"{grid_mean * 1e3:.4f} mm ({100 * (grid_mean / square_mean - 1):+.2f} %); the engine's onset "
            f"{torque_onset * 1e3:.4f} mm ({100 * (torque_onset / square_mean - 1):+.2f} % from the square).")
    return rows + ["", note]


def _say(msg: str) -> None:
    print(f"\r  {msg:<72}", end="", file=sys.stderr, flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, help="folder for the recordings (<scenario>.mcap + .json each)")
    ap.add_argument("--scenarios", nargs="+", default=list(ALL_SCENARIOS), metavar="NAME",
                    help="scenario names or prefixes (default: all; --list shows them)")
    ap.add_argument("--list", action="store_true", help="list the scenarios and exit")
    ap.add_argument("--ft-rate", type=float, default=1000.0, help="F/T rate, Hz (1000 / n; default 1000)")
    ap.add_argument("--tactile-rate", type=float, default=1000.0,
                    help="tactile rate, Hz (1000 / n; default 1000; 0: no tactile/frame)")
    ap.add_argument("--truth-rate", type=float, default=1000.0,
                    help="rig/truth rate, Hz (1000 / n; default 1000; 0: none, as from hardware)")
    ap.add_argument("--seed", type=int, default=0, help="sensor noise seed (default 0)")
    ap.add_argument("--validate", action="store_true", help="slow ramps against the analytic limits; print a table")
    args = ap.parse_args()
    if args.validate:
        t0 = time.process_time()
        lines = validate(_say)
        print(f"\n" + "\n".join(lines) + f"\n\n{time.process_time() - t0:.1f} s CPU")
        return
    if args.list:
        for s in ALL_SCENARIOS.values():
            print(f"{s.name:<32} {s.duration_s:4.1f} s  {s.description}")
        return
    if args.out is None:
        ap.error("--out DIR is required (or --list)")
    chosen = [s for s in ALL_SCENARIOS.values() if any(s.name.startswith(p) for p in args.scenarios)]
    if not chosen:
        ap.error(f"no scenario matches {args.scenarios}; --list shows them")
    rates = Rates(args.ft_rate, args.tactile_rate, args.truth_rate)
    for s in chosen:
        g = generate(s, args.out, rates, seed=args.seed, say=_say)
        eps = ", ".join(f"{a:.3f}-{b:.3f}" for a, b in g.summary["episodes_s"]) or "none"
        _say(f"{s.name}: {g.cpu_s:.1f} s CPU, {g.summary['bytes'] / 1e3:.0f} kB, slip {eps}\n")
    print(f"wrote {len(chosen)} recordings; index: {write_readme(args.out)}")


if __name__ == "__main__":
    main()
