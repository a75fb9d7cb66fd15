"""slip_detector: the slip verdict from each ``contact`` (docs/math.md §3).

The chosen ``method`` decides; the cheaper tests in ``also`` are computed alongside
and published in ``verdicts`` (name → [stick, margin]) so their agreement can be
watched and recorded. A :class:`~slipstack.lib.detection.SlipLatch` turns the
method's margin into the latched state (onset band ``delta``, hysteresis
``gamma_release``, ``release_ms``).

The detector computes its verdict from ``contact`` directly rather than waiting for
``cor``: one hop less between the sensor sample and the grip command. Its own COR of
impending slip warm-starts the next frame.

The F/T tests need a torsional coefficient β: ``beta_m`` if set, otherwise β_s from
the tactile data (docs/math.md §4.3), computed once per tactile frame (β_s depends only
on the shape of the pressure, not on its size) and shared by every F/T test.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from slipstack.lib.detection import DetectorConfig, SlipLatch
from slipstack.lib.limit_set import compile_kernels, torsional_coefficient
from slipstack.lib.slip_tests import SLIP_TESTS, SlipParams, get_slip_test
from slipstack.lib.status import SolverStatus
from slipstack.messages import STATUS_OK, Contact, Slip
from slipstack.nodes.contact_view import ContactView
from slipstack.nodes.material_param import DEFAULT_MATERIAL, fill_from_material
from slipstack.nodes.node import Context, Input, Node, Output

__all__ = ["SlipDetector", "SlipDetectorParams"]

_FT_TESTS = ["coulomb", "decoupled", "linear_ls", "elliptic_ls"]


@dataclass(frozen=True)
class SlipDetectorParams:
    method: str = field(default="exact", metadata={"help": f"deciding test: one of {sorted(SLIP_TESTS)}"})
    also: list[str] = field(default_factory=lambda: list(_FT_TESTS), metadata={"help": "tests published alongside"})
    material: str = field(default=DEFAULT_MATERIAL, metadata={
        "help": "material file (launch/materials/ name or path): mu, delta, gamma_release unless given"})
    mu: float = field(default=math.nan, metadata={"help": "static friction coefficient; nan: the material's mu_s"})
    beta_m: float = field(default=0.0, metadata={"help": "torsional coefficient for F/T tests (m); 0: from tactile"})
    delta: float = field(default=math.nan, metadata={
        "help": "onset band: slip when gamma >= 1 - delta; nan: from the material (lib/material.py)"})
    gamma_release: float = field(default=math.nan, metadata={
        "help": "slip stays latched while gamma >= this (just below mu_d/mu_s); nan: from the material"})
    release_ms: float = field(default=DetectorConfig.release_ns / 1e6,
                              metadata={"help": "gamma below release this long -> stick (ms)"})
    pool: int = field(default=1, metadata={"help": "sum taxels in pool x pool blocks before testing (1: off)"})

    def __post_init__(self) -> None:
        fill_from_material(self, mu="mu_s", delta="delta", gamma_release="gamma_release")


class SlipDetector(Node):
    """Publishes ``slip`` for every contact."""

    name = "slip_detector"
    inputs = {"contact": Input("contact", Contact)}
    outputs = {"slip": Output("slip", Slip)}
    Params = SlipDetectorParams

    def __init__(self, params: SlipDetectorParams | None = None) -> None:
        super().__init__(params)
        p = self.params
        self.test = get_slip_test(p.method)
        self.others = [(name, get_slip_test(name)) for name in p.also if name != p.method]
        self.slip_params = SlipParams(mu=p.mu, beta_m=p.beta_m or None, delta=p.delta)
        self._ft_params = self.slip_params  # with β_s of the current tactile frame when beta_m is 0
        self._beta_frame: int | None = None
        self.latch = SlipLatch(DetectorConfig(p.delta, p.gamma_release, round(p.release_ms * 1e6)))
        self._warm: tuple[float, float] | None = None
        self._kind = "translation"  # the latest slip kind, reported while the latch holds

    def _params_for_ft_tests(self, msg: Contact, view: ContactView) -> SlipParams:
        """SlipParams with β fixed: the configured one, or β_s of this tactile frame."""
        if self.slip_params.beta_m is not None or not view.phi.size:
            return self.slip_params
        frame = msg.header.sources.get("tactile")
        if frame != self._beta_frame:
            tor = torsional_coefficient(view.phi, view.positions, self.slip_params.mu)
            beta = tor.beta_m if tor.status.usable and tor.median is not None else None
            self._ft_params = replace(self.slip_params, beta_m=beta) if beta else self.slip_params
            self._beta_frame = frame
        return self._ft_params

    def _verdict_status(self, msg: Contact, solver: SolverStatus) -> str:
        """``ok`` when the verdict judged valid data; otherwise why not: the contact's
        status, ``tactile_<why>`` for a tactile test without a paired frame, or the
        solver's status."""
        if msg.status != STATUS_OK:
            return msg.status
        if not msg.has_tactile and self.params.method not in _FT_TESTS:
            # a contact without a frame that claims its pairing was fine contradicts itself
            return f"tactile_{msg.tactile_status if msg.tactile_status != STATUS_OK else 'fault'}"
        return STATUS_OK if solver.usable else solver.value

    def start(self, ctx: Context) -> None:
        compile_kernels()  # before the node reports ready, so its first contact runs at full speed

    def on_contact(self, msg: Contact, ctx: Context) -> None:
        stamp = msg.header.stamp_ns
        view = ContactView(msg, self.params.pool)
        ft_params = self._params_for_ft_tests(msg, view)
        v = self.test(view, ft_params if self.params.method in _FT_TESTS else self.slip_params, self._warm)
        if v.p_c is not None:
            self._warm = v.p_c
        # Stale or invalid input, or a tactile test without a tactile frame, says nothing
        # new: the latch keeps its state (never "released" by a sensor hiccup); only a
        # real loss of contact clears it. The verdict's status says why it is not valid,
        # so the grip controller holds instead of reading the load as zero.
        status = self._verdict_status(msg, v.status)
        fresh = status == STATUS_OK
        in_contact = v.kind != "no-contact" if fresh else msg.status != "no_contact"
        slipping = self.latch.update(stamp, v.margin if fresh else float("nan"), in_contact=in_contact)
        verdicts = {v.method: [v.stick, v.margin]}
        for name, test in self.others:
            o = test(view, ft_params, None)
            verdicts[name] = [o.stick, o.margin]
        if not in_contact:
            state = "no-contact"
        elif slipping:
            if v.kind not in ("stick", "no-contact"):
                self._kind = v.kind
            state = self._kind
        else:
            state = "stick"
        if not v.status.usable:
            ctx.count(f"slip.{v.status.value}")
        ctx.publish("slip", Slip(state=state, margin=v.margin, method=v.method, verdicts=verdicts,
                                 gamma=v.gamma, status=status, f_n=msg.f_n, f_t=msg.f_t, tau=msg.tau,
                                 p_c=np.array(v.p_c if v.p_c is not None else (0.0, 0.0)),
                                 p_c_valid=v.p_c is not None),
                    stamp_ns=stamp, sources=msg.header.sources)
