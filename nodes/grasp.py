"""grasp: two fingers' slip verdicts → one verdict and one squeeze command (docs/math.md §9).

More in docs/modules.md, `nodes/grasp.py`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from slipstack.lib.contact_view import pad_positions
from slipstack.lib.errors import ConfigError
from slipstack.lib.grasp import (
    PIVOT_GAINS, SLIDE_GAINS, MotionEstimator, SqueezeLaw, TextureOdometer, TrackControl, combined_contact,
    least_squeeze, load_shares, pad_pose, predict_turn, to_finger0)
from slipstack.lib.grip_laws import GripGovernor, GripInput, GripReason
from slipstack.lib.limit_set import compile_kernels
from slipstack.lib.status import SLIP_STATES, SlipState
from slipstack.messages import Contact, GraspGoal, GraspState, GripCommand, Slip
from slipstack.messages.types import MAX_GRIP_FORCE_N
from slipstack.nodes.material_param import DEFAULT_MATERIAL, fill_from_material
from slipstack.nodes.runtime.node import Context, Input, Node, Output

__all__ = ["Grasp", "GraspParams"]

_MOVING_M_S, _MOVING_RAD_S = 4e-3, 0.15
"""The pads see the object move faster than these (m/s, rad/s): it slides (their noise reaches ~1 mm/s, 3°/s)."""
_SETTLE_NS = 300_000_000
"""After a pivot or slide ends, the regrip squeeze is kept this long before the hold law takes over."""


def _one_pad_geometry(c0: Contact | None, c1: Contact | None) -> bool:
    """Both fingers' contacts carry a pressure frame of one pad geometry (rows, cols, a pitch > 0):
    what the pads' joint view of the object needs. The decoder admits others (pitch 0, unlike pads)."""
    return (c0 is not None and c1 is not None and c0.has_tactile and c1.has_tactile and c0.phi.size > 0
            and c0.pitch_m > 0.0 and (c0.rows, c0.cols, c0.pitch_m) == (c1.rows, c1.cols, c1.pitch_m))


@dataclass(frozen=True)
class GraspParams:
    material: str = field(default=DEFAULT_MATERIAL, metadata={
        "help": "material file (launch/materials/ name or path): mu_s and mu_d unless given"})
    mu: float = field(default=math.nan, metadata={"help": "static friction coefficient; nan: the material's mu_s"})
    mu_d: float = field(default=math.nan, metadata={"help": "sliding friction coefficient; nan: the material's"})
    sigma: float = field(default=0.85, metadata={
        "help": "hold: the squeeze is the least holding one over sigma (<= 1)"})
    f_nom_n: float = field(default=5.0, metadata={"help": "lowest squeeze commanded (N; the WSG 50's least: 5 N)"})
    f_max_n: float = field(default=60.0, metadata={"help": "highest squeeze commanded (N)"})
    max_rate_n_per_s: float = field(default=400.0, metadata={"help": "squeeze slew limit (N/s)"})
    timeout_ms: float = field(default=20.0, metadata={"help": "inputs older than this hold the squeeze (ms)"})
    blind_grace_ms: float = field(default=50.0, metadata={
        "help": "fail-safe this long with a loaded contact starts raising the squeeze (ms); < 0: never"})
    blind_rise_n_per_s: float = field(default=10.0, metadata={"help": "rate of that raise (N/s)"})
    ridge_period_m: float = field(default=0.0, metadata={
        "help": "period of the ridges on the object's face the pads see (m); a slide needs them; 0: none"})
    state_period_ms: float = field(default=10.0, metadata={"help": "grasp/state at most this often (ms)"})
    hold_fall_n_per_s: float = field(default=5.0, metadata={
        "help": "hold: the squeeze follows a falling load down at most this fast (N/s); a rising one at once"})

    def __post_init__(self) -> None:
        fill_from_material(self, mu="mu_s", mu_d="mu_d")
        if not (0.0 < self.sigma <= 1.0):
            raise ConfigError(f"grasp: sigma must lie in (0, 1], got {self.sigma!r}")
        if not (0.0 < self.mu_d <= self.mu):
            raise ConfigError(f"grasp: mu_d must lie in (0, mu = {self.mu}], got {self.mu_d!r}")
        if self.ridge_period_m < 0.0:
            raise ConfigError(f"grasp: ridge_period_m must be >= 0 m, got {self.ridge_period_m!r}")


class Grasp(Node):
    """The two-finger grasp: one verdict, one squeeze, and the hold, pivot and slide modes."""

    name = "grasp"
    inputs = {
        "slip0": Input("finger0/slip", Slip),
        "slip1": Input("finger1/slip", Slip),
        "contact0": Input("finger0/contact", Contact),
        "contact1": Input("finger1/contact", Contact),
        "goal": Input("grasp/goal", GraspGoal, policy="queue", depth=16),
    }
    outputs = {"command": Output("grip/command", GripCommand), "slip": Output("slip", Slip),
               "state": Output("grasp/state", GraspState)}
    Params = GraspParams

    def __init__(self, params: GraspParams | None = None) -> None:
        super().__init__(params)
        p = self.params
        self.law = SqueezeLaw(f_nom_n=p.f_nom_n, f_max_n=p.f_max_n)
        self.governor = GripGovernor(self.law, timeout_ns=round(p.timeout_ms * 1e6),
                                     max_rate_n_per_s=p.max_rate_n_per_s,
                                     blind_grace_ns=round(p.blind_grace_ms * 1e6),
                                     blind_rise_n_per_s=p.blind_rise_n_per_s)
        self.slips: list[Slip | None] = [None, None]
        self.contacts: list[Contact | None] = [None, None]
        self.mode = "hold"
        self.goal: GraspGoal | None = None
        self.control: TrackControl | None = None
        self.sense = 1
        self.ended = ""
        self._regrip_n = 0.0
        self._regrip_until_ns = 0
        self._frames: list[int | None] = [None, None]  # the tactile stamps of the pads' newest frames
        self._motion: MotionEstimator | TextureOdometer | None = None  # a mode's
        self._watch = MotionEstimator()  # the pads' view of the object, for the hold
        self._progress = (0.0, 0.0)
        self._last_state_ns: int | None = None
        self._last_publish_ns = 0
        self._last_stamp_ns = -1  # the newest sample stamp a command was published for
        self._judged_ns = [-1, -1]  # each finger's newest verdict stamp judged
        self._commanded_verdict_ns = -1  # the newest verdict stamp a command was published for
        self._phase = "hold"
        self._fail_safe = False
        self._hold_n, self._hold_ns = math.nan, 0  # the hold's demand at the last step (N, ns)
        self._load_at_start = math.nan  # the mode's load when it began (N·m or N)

    def start(self, ctx: Context) -> None:
        compile_kernels()  # before the node reports ready: its first prediction runs at full speed

    # -- inputs ------------------------------------------------------------------------------------
    def on_contact0(self, msg: Contact, ctx: Context) -> None:
        self._take_contact(0, msg, ctx)

    def on_contact1(self, msg: Contact, ctx: Context) -> None:
        self._take_contact(1, msg, ctx)

    def on_slip0(self, msg: Slip, ctx: Context) -> None:
        self.slips[0] = msg
        self._step(ctx, finger=0)

    def on_slip1(self, msg: Slip, ctx: Context) -> None:
        self.slips[1] = msg
        self._step(ctx, finger=1)

    def on_goal(self, msg: GraspGoal, ctx: Context) -> None:
        ctx.count("grasp.goals")
        if msg.mode == "hold":
            self._end("ended by a hold goal", ctx)
            return
        why = self._begin(msg, ctx.now_ns())
        if why:
            ctx.count("grasp.goals_refused")
            self.ended = f"refused: {why}"
            ctx.report_error(f"grasp: {msg.mode} goal refused: {why}")
        else:
            ctx.count(f"grasp.{msg.mode}s")
            ctx.log(f"{msg.mode} by {msg.angle_rad if msg.mode == 'pivot' else msg.distance_m:g} "
                    f"{'rad' if msg.mode == 'pivot' else 'm'} at {msg.rate_rad_s if msg.mode == 'pivot' else msg.speed_m_s:g}"
                    f" {'rad/s' if msg.mode == 'pivot' else 'm/s'}: from {self.control.start_n:.2f} N "
                    f"(kinetic {self.control.kinetic_n:.2f} N, floor {self.control.floor_n:.2f} N)")
        self._publish_state(ctx, force=True)

    def next_deadline_ns(self) -> int | None:
        """Watchdog: one timeout after the last command (none before the first verdict)."""
        return None if self.slips[0] is None and self.slips[1] is None else (
            self._last_publish_ns + self.governor.timeout_ns)

    def on_deadline(self, ctx: Context) -> None:
        self._step(ctx, verdict_missing=True)

    # -- the step ----------------------------------------------------------------------------------
    def _step(self, ctx: Context, *, verdict_missing: bool = False, finger: int | None = None) -> None:
        now = ctx.now_ns()
        s0, s1 = self.slips
        stamps = [s.header.stamp_ns for s in (s0, s1) if s is not None]
        ok = not verdict_missing and s0 is not None and s1 is not None and s0.status == "ok" and s1.status == "ok"
        least = self._least(s0, s1) if s0 is not None and s1 is not None else math.nan
        if self.control is not None:
            c0, c1 = self.contacts
            stamps += [c.header.stamp_ns for c in (c0, c1) if c is not None]
            ok = ok and _one_pad_geometry(c0, c1)
        demand = self._demand(now, least) if ok else math.nan
        known = [s.f_n for s in (s0, s1) if s is not None]
        f_n = sum(known) / len(known) if known else math.nan  # both pads feel the one squeeze
        loaded = any(s is not None and s.state != SlipState.NO_CONTACT for s in (s0, s1))
        decision = self.governor.step(GripInput(demand_n=demand, f_n=f_n), now_ns=now, stamps_ns=stamps or [],
                                      status_ok=ok, loaded=loaded)
        if decision is None:  # nothing trusted to start from yet (docs/safety.md): no command, the gripper keeps its grip
            ctx.count("grip.waiting_to_start")
            ctx.set_status("starting", "no trusted verdict of both fingers yet: no command, the gripper keeps its grip")
            return
        self._fail_safe = decision.reason is GripReason.FAIL_SAFE
        if self._fail_safe:
            ctx.count("grip.fail_safe_steps")
            if self.control is not None:
                self._end("fail-safe: " + (decision.detail or "input not ok"), ctx)
            ctx.set_status("fail-safe", decision.detail or "input status not ok")
        else:
            ctx.set_status("ok")
        stamp = max(stamps) if stamps else now
        sources = {}  # each finger's verdict and the samples it derives from: slip0, ft0, tactile0, ..., slip1, ...
        for k, s in enumerate((s0, s1)):
            if s is not None:
                sources[f"slip{k}"] = s.header.stamp_ns
                sources.update({f"{key}{k}": v for key, v in s.header.sources.items()})
        sources["slip"] = max((s.header.stamp_ns for s in (s0, s1) if s is not None), default=stamp)
        # A command for every verdict on a sample not judged yet: each finger's sensor has its own
        # clock, so a verdict may be older than the other finger's last one and still be new. Both
        # fingers' verdicts of one instant (one stamp: lock-step) make one command, not two. Only
        # verdict stamps tell the instant: in a mode a contact may be newer than either verdict.
        own = self.slips[finger].header.stamp_ns if finger is not None else -1
        new = finger is not None and own > self._judged_ns[finger] and own != self._commanded_verdict_ns
        if verdict_missing or stamp > self._last_stamp_ns or new:
            ctx.publish("command", GripCommand(f_n_desired=float(decision.f_n_desired), law="grasp",
                                               reason=decision.reason.value), stamp_ns=stamp, sources=sources)
            self._last_publish_ns, self._last_stamp_ns = now, max(stamp, self._last_stamp_ns)
            self._commanded_verdict_ns = max(self._commanded_verdict_ns, own)
        if finger is not None:
            self._judged_ns[finger] = max(own, self._judged_ns[finger])
        if s0 is not None and s1 is not None:
            self._publish_verdict(s0, s1, stamp, sources, ctx)
        self._publish_state(ctx, least=least)

    def _least(self, s0: Slip, s1: Slip) -> float:
        """The least squeeze that holds both contacts (:func:`~slipstack.lib.grasp.least_squeeze`)."""
        return least_squeeze((s0.gamma, s1.gamma), (s0.f_n, s1.f_n))

    def _sliding(self, now: int, least: float) -> None:
        """While the pads see the object move and a finger's verdict is slip, that contact
        transmits only its sliding friction: the load to hold is ``μ_s/μ_d`` times the one it
        carries (docs/math.md §9). The squeeze is raised to hold that, and kept there
        ``_SETTLE_NS`` (else it would follow a sliding contact's falling load down, and drop
        again as soon as the object stopped)."""
        s0, s1 = self.slips
        motion = self._watch.motion
        if not (motion.speed > _MOVING_M_S or abs(motion.rate) > _MOVING_RAD_S):
            return
        if not any(s.state in SLIP_STATES for s in (s0, s1)):
            return
        p = self.params
        self._regrip_n = max(self._regrip_n if now < self._regrip_until_ns else 0.0, least * p.mu / p.mu_d / p.sigma)
        self._regrip_until_ns = now + _SETTLE_NS
        self._phase = "regrip"

    def _demand(self, now: int, least: float) -> float:
        """The squeeze the mode asks for now (N), before the governor. In hold it follows a
        rising load at once and a falling one at ``hold_fall_n_per_s`` (a vibrating object's
        load dips between its peaks; following the dips down lets it slip: a bar ringing after
        a pivot, its peaks ~55 ms apart, crept 4° in 6 s at 20 N/s, not at 5 N/s)."""
        hold = least / self.params.sigma
        if self.control is None:
            self._sliding(now, least)
            fall = self.params.hold_fall_n_per_s * max(now - self._hold_ns, 0) * 1e-9
            hold = max(hold, self._hold_n - fall) if self._hold_n == self._hold_n else hold
            self._hold_n, self._hold_ns = hold, now
            return max(hold, self._regrip_n) if now < self._regrip_until_ns else hold
        self._hold_n = math.nan
        progress, rate = self._progress
        out = self.control.step(now, self.sense * progress, self.sense * rate, least, self._load_share())
        self._phase = out.phase
        if out.ended:
            self._regrip_n, self._regrip_until_ns = out.demand_n, now + _SETTLE_NS
            self.ended = out.ended
            self.control = None
            self.mode = "hold"
        return out.demand_n

    def _mode_load(self) -> float:
        """The load a pivot (the torque) or a slide (the force) turns on, both fingers' in finger
        0's frame (N·m or N; NaN without both verdicts)."""
        s0, s1 = self.slips
        if s0 is None or s1 is None:
            return math.nan
        (f1x, f1y), tau1 = to_finger0((float(s1.f_t[0]), float(s1.f_t[1])), s1.tau)
        if self.mode == "pivot":
            return abs(s0.tau + tau1)
        return math.hypot(s0.f_t[0] + f1x, s0.f_t[1] + f1y)

    def _load_share(self) -> float:
        load = self._mode_load()
        return load / self._load_at_start if self._load_at_start > 0.0 and load == load else 1.0

    def _phase_now(self, now: int) -> str:
        if self._fail_safe:
            return "fail-safe"
        if self.control is not None:
            return self._phase
        return "regrip" if now < self._regrip_until_ns else "hold"

    # -- modes -------------------------------------------------------------------------------------
    def _begin(self, goal: GraspGoal, now: int) -> str:
        """Start ``goal``'s mode; the reason it cannot start ('' if it did)."""
        s0, s1 = self.slips
        c0, c1 = self.contacts
        if s0 is None or s1 is None or not _one_pad_geometry(c0, c1):
            return "both fingers' verdicts and pressure frames of one pad geometry are needed first"
        if goal.mode == "pivot" and not (goal.angle_rad > 0.0 and goal.rate_rad_s > 0.0):
            return "a pivot needs angle_rad > 0 and rate_rad_s > 0"
        if goal.mode == "slide" and not (goal.distance_m > 0.0 and goal.speed_m_s > 0.0):
            return "a slide needs distance_m > 0 and speed_m_s > 0"
        positions = pad_positions(c0.rows, c0.cols, c0.pitch_m)
        loads = tuple(((float(c.f_t[0]), float(c.f_t[1])), float(c.tau)) for c in (c0, c1))
        phi, pos, f_t, tau = combined_contact((c0.phi, c1.phi), positions, loads)
        p = self.params
        prediction = predict_turn(phi, pos, f_t, tau, 0.5 * (c0.f_n + c1.f_n), p.mu, p.mu_d)
        if not prediction.usable:
            return "the limit set of both pads has no answer for this load"
        poses = (pad_pose(c0.phi, positions), pad_pose(c1.phi, positions))
        if poses[0] is None or poses[1] is None:
            return "a pad is not in contact"
        if goal.mode == "pivot":
            if prediction.sense == 0:
                return "the load does not turn the object (no torque about its centre of rotation)"
            estimator = MotionEstimator()
            estimator.update(now, poses)
            if not estimator.motion.sees_angle:
                return "the pads cannot see the object's angle (its footprints are not elongated)"
            self.control = TrackControl(goal.angle_rad, goal.rate_rad_s, prediction.start_n, prediction.kinetic_n,
                                        1.5 * prediction.hold_translation_n, now, PIVOT_GAINS)
            self.sense = prediction.sense
            self._motion = estimator
        else:
            if p.ridge_period_m <= 0.0:
                return "the pads see a slide only on a ridged face: set ridge_period_m (the ridges' period)"
            norm = math.hypot(*f_t)
            if norm <= 0.0:
                return "no load to slide the object"
            odometer = TextureOdometer(p.ridge_period_m, positions, (f_t[0] / norm, f_t[1] / norm))
            odometer.update(now, (c0.phi, c1.phi))
            if not odometer.sees:
                return f"the pads see no ridges of period {p.ridge_period_m:g} m"
            self.control = TrackControl(goal.distance_m, goal.speed_m_s, prediction.start_n, prediction.kinetic_n,
                                        p.f_nom_n, now, SLIDE_GAINS)
            self.sense = 1
            self._motion = odometer
        self.goal, self.mode, self.ended = goal, goal.mode, ""
        self._load_at_start = self._mode_load()
        self._frames = [c0.header.sources.get("tactile"), c1.header.sources.get("tactile")]
        self._progress = (0.0, 0.0)
        return ""

    def _end(self, why: str, ctx: Context) -> None:
        if self.control is not None:
            ctx.count("grasp.modes_ended")
            ctx.log(f"{self.mode} ended: {why}")
            self.ended = why
        self.control = None
        self.mode = "hold"

    def _take_contact(self, k: int, msg: Contact, ctx: Context) -> None:
        """Keep finger ``k``'s contact; once both pads have a new pressure frame, update what
        the pads see of the object's motion."""
        self.contacts[k] = msg
        if not msg.has_tactile:
            return
        frame = msg.header.sources.get("tactile")
        if frame == self._frames[k]:
            return
        self._frames[k] = frame
        other = self.contacts[1 - k]
        if k == 0 or other is None or not other.has_tactile:
            return  # finger 1's frame completes the pair (both pads are sampled together)
        c0, c1 = self.contacts
        if not _one_pad_geometry(c0, c1):
            ctx.count("grasp.pads_unlike")  # no joint view of the object: what it saw is forgotten
            self._watch.reset()
            return
        now = ctx.now_ns()
        positions = pad_positions(c0.rows, c0.cols, c0.pitch_m)
        poses = (pad_pose(c0.phi, positions), pad_pose(c1.phi, positions))
        if poses[0] is None or poses[1] is None:
            self._watch.reset()
            return
        self._watch.update(now, poses)
        if isinstance(self._motion, MotionEstimator):
            motion = self._motion.update(now, poses)
            self._progress = (motion.angle, motion.rate)
        elif isinstance(self._motion, TextureOdometer):
            self._progress = self._motion.update(now, (c0.phi, c1.phi))

    # -- outputs -----------------------------------------------------------------------------------
    def _publish_verdict(self, s0: Slip, s1: Slip, stamp: int, sources: dict[str, int], ctx: Context) -> None:
        """Both fingers' verdicts as one ``slip``: a slip state if either slips, the larger γ,
        the first status that is not ``ok``, the load both carry in finger 0's frame."""
        states = (s0.state, s1.state)
        state = next((s for s in states if s in SLIP_STATES), None) or (
            SlipState.NO_CONTACT.value if SlipState.NO_CONTACT.value in states else SlipState.STICK.value)
        gamma = max(s0.gamma, s1.gamma)
        status = s0.status if s0.status != "ok" else s1.status
        (f1x, f1y), tau1 = to_finger0((float(s1.f_t[0]), float(s1.f_t[1])), s1.tau)
        ctx.publish("slip", Slip(
            state=state, margin=1.0 - gamma, method="grasp", gamma=gamma, status=status,
            verdicts={"finger0": [s0.state == SlipState.STICK.value, s0.margin],
                      "finger1": [s1.state == SlipState.STICK.value, s1.margin]},
            f_n=0.5 * (s0.f_n + s1.f_n), f_t=np.array([s0.f_t[0] + f1x, s0.f_t[1] + f1y]), tau=s0.tau + tau1),
            stamp_ns=stamp, sources=sources)

    def _publish_state(self, ctx: Context, *, least: float = math.nan, force: bool = False) -> None:
        now = ctx.now_ns()
        period = round(self.params.state_period_ms * 1e6)
        if not force and self._last_state_ns is not None and now - self._last_state_ns < period:
            return
        self._last_state_ns = now
        s0, s1 = self.slips
        have = s0 is not None and s1 is not None
        gamma = np.array([s0.gamma, s1.gamma] if have else [math.nan, math.nan])
        f_n = np.array([s0.f_n, s1.f_n] if have else [0.0, 0.0])
        share = load_shares(((float(s0.f_t[0]), float(s0.f_t[1])), (float(s1.f_t[0]), float(s1.f_t[1])))) if have else (0.5, 0.5)
        control = self.control
        progress, rate = self._progress
        target = 0.0 if self.goal is None else (self.goal.angle_rad if self.goal.mode == "pivot" else self.goal.distance_m)
        predicted = control.kinetic_n if control is not None else (least / self.params.sigma if least == least else 0.0)
        translation = 0.0
        if isinstance(self._motion, MotionEstimator):
            translation = math.hypot(*self._motion.motion.shift)
        ctx.publish("state", GraspState(
            mode=self.mode, phase=self._phase_now(now),
            ended=self.ended[:256], target=target, progress=float(self.sense * progress), rate=float(self.sense * rate),
            translation_m=float(translation), least_n=_bounded(least), predicted_n=_bounded(predicted),
            gamma=gamma, f_n=np.where(np.isfinite(f_n), f_n, 0.0), share=np.array(share)), stamp_ns=now)


def _bounded(force_n: float) -> float:
    """A force for a message field bounded to [0, MAX_GRIP_FORCE_N] (NaN → 0)."""
    return 0.0 if not force_n == force_n else min(max(force_n, 0.0), MAX_GRIP_FORCE_N)
