"""grip_controller: the grip-force law of docs/math.md §5 behind a fail-safe governor.

More in docs/modules.md, `nodes/grip_controller.py`.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from slipstack.lib.contact_view import pad_positions
from slipstack.lib.errors import ConfigError
from slipstack.lib.defaults import F_MAX_N
from slipstack.lib.grip_laws import (LAWS, NOT_OK, FingerReport, GripDecision, GripGovernor, GripInput, GripReason,
                                      make_law)
from slipstack.lib.status import SlipCase, SlipState
from slipstack.messages import Contact, Cor, GripCommand, GripState, Slip
from slipstack.nodes.material_param import DEFAULT_MATERIAL, fill_from_material
from slipstack.nodes.runtime.node import Context, Input, Node, Output
from slipstack.nodes.runtime.remote_sources import remote_sources

__all__ = ["GripController", "GripControllerParams", "INCREMENTS"]

INCREMENTS = ("total", "per_taxel")
"""Law (14)'s raise: the total δf_n = N_A·δφ, or the per-taxel δφ the paper prints."""


@dataclass(frozen=True)
class GripControllerParams:
    law: str = field(default="exact", metadata={"help": f"grip law: one of {sorted(LAWS)}"})
    f_nom_n: float = field(default=2.0, metadata={"help": "lowest commanded normal force (N)"})
    f_max_n: float = field(default=F_MAX_N, metadata={"help": "highest commanded normal force (N)"})
    material: str = field(default=DEFAULT_MATERIAL, metadata={
        "help": "material file (launch/materials/ name or path): mu, beta_m, delta, gamma_release unless given"})
    mu: float = field(default=math.nan, metadata={"help": "static friction coefficient used by the law; nan: mu_s"})
    sigma: float = field(default=0.5, metadata={"help": "safety factor sigma <= 1"})
    beta_m: float = field(default=math.nan, metadata={
        "help": "torsional coefficient beta (m) for ft13 laws; nan or 0 (the launch files' 'from data'): "
                "the material's beta_s"})
    k_n: float = field(default=2.0, metadata={"help": "offset k (N) of law (13)"})
    cone_margin_n: float = field(default=1.0, metadata={
        "help": "cone_margin (the paper's ref. [9]): distance kept from the friction cone's border (N)"})
    increment: str = field(default="total", metadata={
        "help": "(14): 'total' N_A*dphi, or 'per_taxel' dphi as the paper prints it (under-raises)"})
    decay_n_per_s: float = field(default=0.0, metadata={"help": "(14): release rate while (11) holds (N/s)"})
    delta: float = field(default=math.nan, metadata={
        "help": "(14): onset band: (11) counts as failing once |n| > (1 - delta) T; nan: from the material"})
    gamma_release: float = field(default=math.nan, metadata={
        "help": "(14): while slip is reported, (11) fails once |n| > gamma_release T; nan: from the material"})
    max_rate_n_per_s: float = field(default=200.0, metadata={"help": "actuator slew limit (N/s)"})
    timeout_ms: float = field(default=20.0, metadata={"help": "inputs older than this hold the grip (ms)"})
    blind_grace_ms: float = field(default=50.0, metadata={
        "help": "fail-safe this long with a loaded contact starts raising the grip (ms); < 0: never"})
    blind_rise_n_per_s: float = field(default=10.0, metadata={"help": "rate of that raise (N/s)"})
    f_hold_n: float = field(default=math.nan, metadata={
        "help": "first command on untrusted data when the finger reports nothing on grip/state (N); "
                "nan: none, no command until trusted data or the finger's report (the finger keeps its grip)"})
    finger_wait_ms: float = field(default=100.0, metadata={
        "help": "how long a first command on untrusted data waits for the finger's report before f_hold_n (ms)"})

    def __post_init__(self) -> None:
        if self.increment not in INCREMENTS:  # checked for every law: a typo must not pass silently
            raise ConfigError(f"grip_controller increment must be one of {', '.join(INCREMENTS)}, "
                              f"got {self.increment!r}")
        if self.beta_m == 0.0:  # no law can use a zero β: the launch argument's "from data" default
            object.__setattr__(self, "beta_m", math.nan)
        fill_from_material(self, mu="mu_s", beta_m="beta_s_m", delta="delta", gamma_release="gamma_release")


class GripController(Node):
    """Commands the normal force from the slip verdict, contact load and COR."""

    name = "grip_controller"
    inputs = {
        "slip": Input("slip", Slip),
        "finger": Input("grip/state", GripState),
        "contact": Input("contact", Contact),
        "cor": Input("cor", Cor),
    }
    outputs = {"command": Output("grip/command", GripCommand)}
    Params = GripControllerParams

    def __init__(self, params: GripControllerParams | None = None) -> None:
        super().__init__(params)
        p = self.params
        if p.law != "tactile14":
            self.inputs = {"slip": self.inputs["slip"], "finger": self.inputs["finger"]}
        law_cls = LAWS.get(p.law)
        accepted = {f.name for f in dataclasses.fields(law_cls)} if law_cls else set()
        law_params = {k: v for k, v in dataclasses.asdict(p).items() if k in accepted}
        self.law = make_law(p.law, **law_params)
        self.governor = GripGovernor(self.law, timeout_ns=round(p.timeout_ms * 1e6), max_rate_n_per_s=p.max_rate_n_per_s,
                                     f_hold_n=None if math.isnan(p.f_hold_n) else p.f_hold_n,
                                     finger_wait_ns=round(p.finger_wait_ms * 1e6),
                                     blind_grace_ns=round(p.blind_grace_ms * 1e6),
                                     blind_rise_n_per_s=p.blind_rise_n_per_s)
        self.contact: Contact | None = None
        self.cor: Cor | None = None
        self.slip: Slip | None = None
        self.finger: GripState | None = None
        self._last_step_ns = 0
        self._remote_sources = remote_sources()  # read here: a malformed map is refused before the node runs
        self._remote_label = ""
        """The other machines the inputs' data comes from ("" on one machine); set in ``start``."""
        self._rotation: tuple[np.ndarray, Cor, tuple[int, int, float], dict[str, object]] | None = None
        """The mask, COR and pad (rows, cols, pitch) of the latest :meth:`_rotation_inputs`, and them."""

    def start(self, ctx: Context) -> None:
        topics = {ctx.input_topic(name) for name in self.inputs}  # as remapped in this graph
        self._remote_label = " or ".join(sorted({self._remote_sources[t] for t in topics if t in self._remote_sources}))

    def on_contact(self, msg: Contact, ctx: Context) -> None:
        self.contact = msg

    def on_cor(self, msg: Cor, ctx: Context) -> None:
        self.cor = msg

    def on_finger(self, msg: GripState, ctx: Context) -> None:
        if ctx.sender:  # a report only the finger may give: one a tool injected is not what it holds
            ctx.count("grip.injected_finger_reports")
            return
        self.finger = msg

    def on_slip(self, msg: Slip, ctx: Context) -> None:
        if ctx.sender:  # a verdict the graph did not judge: it triggers a hold, never a law step
            ctx.count("grip.injected_verdicts")
            self._step(ctx, distrust=f"slip verdict injected by {ctx.sender}: not trusted")
            return
        self.slip = msg
        self._step(ctx)

    def next_deadline_ns(self) -> int | None:
        """Watchdog: one timeout after the last step (none before the first slip verdict,
        so the actuator keeps its own initial grip until the stack has data)."""
        return None if self.slip is None else self._last_step_ns + self.governor.timeout_ns

    def on_deadline(self, ctx: Context) -> None:
        # no new verdict for a whole timeout: hold (and escalate), never re-run the law on the
        # old inputs (law (14) would lower the command to the lagging measured force)
        self._step(ctx, distrust="no new slip verdict within the timeout")

    def _step(self, ctx: Context, *, distrust: str = "") -> None:
        now = ctx.now_ns()
        self._last_step_ns = now
        inp, stamps, ok = self._gather()
        loaded = self.slip is not None and self.slip.state != SlipState.NO_CONTACT
        finger = None if self.finger is None else FingerReport(self.finger.f_n_command, self.finger.mode != "initial")
        decision = self.governor.step(inp, now_ns=now, stamps_ns=stamps, status_ok=ok and not distrust, loaded=loaded,
                                      finger=finger)
        if decision is None:  # nothing known to start from: no command, the finger keeps its grip
            ctx.count("grip.waiting_to_start")
            ctx.set_status("starting", "no trusted data and no report from the finger (grip/state) yet: "
                                       "no command, the finger keeps its grip")
            return
        if distrust and decision.reason is GripReason.FAIL_SAFE:  # say why, where the status alone was blamed
            decision = dataclasses.replace(decision, detail=decision.detail.replace(NOT_OK, distrust, 1))
        stamp = max(stamps) if stamps else now
        sources = {"slip": self.slip.header.stamp_ns, **self.slip.header.sources} if self.slip else {}
        self._publish(decision, stamp, sources, ctx)

    def _gather(self) -> tuple[GripInput, list[int], bool]:
        s = self.slip
        if s is None:
            return GripInput(), [], False
        stamps = [s.header.stamp_ns]
        ok = s.status == "ok"
        rotation: dict[str, object] = {}
        if self.law.name == "tactile14":
            c, r = self.contact, self.cor
            if c is None or r is None:
                return GripInput(f_n=s.f_n), stamps, False
            stamps += [c.header.stamp_ns, r.header.stamp_ns]
            ok = ok and c.status == "ok"
            rotation = self._rotation_inputs_of(c, r)
        f_x, f_y = s.f_t.tolist()
        return GripInput(f_t=(f_x, f_y), tau=s.tau, f_n=s.f_n, gamma=s.gamma, slip_state=s.state, **rotation), stamps, ok

    def _rotation_inputs_of(self, c: Contact, r: Cor) -> dict[str, object]:
        """:meth:`_rotation_inputs`, computed again only when the contact's mask (a new
        tactile frame: fusion passes one frame's mask on to each contact it pairs with it)
        or the COR changed: a COR comes once per tactile frame, a slip verdict with each
        F/T sample. The key holds the mask and the COR themselves, compared by identity
        (read-only message fields), so a new object never matches an old one's address."""
        pad = (c.rows, c.cols, c.pitch_m)
        cached = self._rotation
        if cached is not None and cached[0] is c.mask and cached[1] is r and cached[2] == pad \
                and not c.mask.flags.writeable:
            return cached[3]
        rotation = self._rotation_inputs(c, r)
        self._rotation = (c.mask, r, pad, rotation)
        return rotation

    @staticmethod
    def _rotation_inputs(c: Contact, r: Cor) -> dict[str, object]:
        """Law (14)'s inputs about the COR ``r`` on the pressure frame of ``c``; a COR
        needs that frame (without one, or on a pad without a pitch, the case is ``none``)."""
        if not c.phi.size or not c.pitch_m > 0.0:
            return {"cor_case": SlipCase.NONE}
        positions = pad_positions(c.rows, c.cols, c.pitch_m)
        p_x, p_y = r.p_c  # each column masked on its own: cheaper than the (N, 2) rows, the same numbers
        dist = positions[:, 0][c.mask] - p_x  # a new array: worked on in place
        y = positions[:, 1][c.mask] - p_y
        dist *= dist
        y *= y
        dist += y
        np.sqrt(dist, out=dist)  # |p_i − p_c| (m), rounded as np.linalg.norm(offsets, axis=1)
        # np.add.reduce: dist.sum() without its Python wrapper (the same pairwise sum)
        return {"n_c": r.load_torque, "t_c": r.torque_capacity, "sum_dist_m": float(np.add.reduce(dist)),
                "n_contact": len(dist), "cor_case": r.case}

    def _publish(self, d: GripDecision, stamp: int, sources: dict[str, int], ctx: Context) -> None:
        reason = d.reason.value
        if d.reason is GripReason.FAIL_SAFE:
            ctx.count("grip.fail_safe_steps")
            if d.detail:
                ctx.set_status("fail-safe", self._name_the_machine(d.detail, ctx.now_ns()))
        else:
            ctx.set_status("ok")
        ctx.publish("command", GripCommand(f_n_desired=float(d.f_n_desired), law=d.law, reason=reason),
                    stamp_ns=stamp, sources=sources)

    def _name_the_machine(self, detail: str, now_ns: int) -> str:
        """``detail``, naming the other machines the inputs come from when an input is a timeout old."""
        if not self._remote_label:
            return detail
        stamps = [m.header.stamp_ns for m in (self.slip, self.contact, self.cor) if m is not None]
        if stamps and now_ns - min(stamps) < self.governor.timeout_ns:
            return detail
        return f"{detail} (from {self._remote_label})"
