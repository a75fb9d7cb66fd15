"""cor_estimator: the centre of rotation of impending slip from each ``contact``.

Solvers (parameter ``solver``): ``exact`` — the load factor γ and the COR of
impending slip (Dinkelbach over the Fermat–Weber sub-solver, docs/math.md §4.2);
``robust`` — the maximiser of ``s·n − T`` over both senses, the paper's (12) solved
globally; ``paper`` — the paper's fixed-gain Jacobian iteration (its Fig. 7), kept as
the faithful baseline. Each frame warm-starts from the previous COR. F/T-only
contacts give case ``none``. With ``per_tactile_frame`` it solves once per new tactile
frame (e.g. 500 Hz) rather than for every contact (the F/T rate), halving its load.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from slipstack.lib.cor import paper_cor, robust_cor
from slipstack.lib.errors import ConfigError
from slipstack.lib.status import CorSolver, SlipCase
from slipstack.lib.limit_set import compile_kernels, load_factor
from slipstack.messages import STATUS_OK, Contact, Cor
from slipstack.lib.contact_view import ContactView, pool_misfit
from slipstack.nodes.material_param import DEFAULT_MATERIAL, fill_from_material
from slipstack.nodes.runtime.node import Context, Input, Node, Output

__all__ = ["CorEstimator", "CorParams", "SOLVERS"]

SOLVERS = tuple(s.value for s in CorSolver)


@dataclass(frozen=True)
class CorParams:
    solver: str = field(default=CorSolver.EXACT.value, metadata={"help": f"one of {SOLVERS}"})
    material: str = field(default=DEFAULT_MATERIAL, metadata={"help": "material file (launch/materials/ name or path)"})
    mu: float = field(default=math.nan, metadata={"help": "static friction coefficient; nan: the material's mu_s"})
    paper_gain: float = field(default=0.5, metadata={"help": "gain h of the paper's iteration (solver=paper)"})
    warm_start: bool = field(default=True, metadata={"help": "start from the previous frame's COR"})
    pool: int = field(default=1, metadata={"help": "sum taxels in pool x pool blocks before solving (1: off)"})
    per_tactile_frame: bool = field(default=False, metadata={
        "help": "solve once per tactile frame (its rate) instead of once per contact (the F/T rate)"})

    def __post_init__(self) -> None:
        if not (isinstance(self.pool, int) and self.pool >= 1):
            raise ConfigError(f"cor_estimator pool must be an integer >= 1 (1: off), got {self.pool!r}")
        fill_from_material(self, mu="mu_s")


class CorEstimator(Node):
    """Publishes ``cor`` for every tactile contact."""

    name = "cor_estimator"
    inputs = {"contact": Input("contact", Contact)}
    outputs = {"cor": Output("cor", Cor)}
    Params = CorParams

    def __init__(self, params: CorParams | None = None) -> None:
        super().__init__(params)
        if self.params.solver not in SOLVERS:
            raise ConfigError(f"cor_estimator solver must be one of {SOLVERS}, got {self.params.solver!r}")
        self._last_pc: tuple[float, float] | None = None
        self._last_frame: int | None = None
        self._said_pool_misfit = False

    def start(self, ctx: Context) -> None:
        compile_kernels()  # before the node reports ready, so its first contact runs at full speed

    def on_contact(self, msg: Contact, ctx: Context) -> None:
        stamp = msg.header.stamp_ns
        if not msg.has_tactile or msg.status != STATUS_OK:
            ctx.publish("cor", Cor(case=SlipCase.NONE, p_c=np.zeros(2), status=msg.status), stamp_ns=stamp,
                        sources=msg.header.sources)
            return
        if self.params.per_tactile_frame:
            frame = msg.header.sources.get("tactile")
            if frame == self._last_frame:
                ctx.count("cor.skipped_same_tactile_frame")
                return
            self._last_frame = frame
        if not self._said_pool_misfit and (misfit := pool_misfit(msg, self.params.pool)):
            self._said_pool_misfit = True
            ctx.report_error(misfit)
        view = ContactView(msg, self.params.pool)
        c0 = self._last_pc if self.params.warm_start else None
        p = self.params
        if p.solver == CorSolver.EXACT:
            r = load_factor(view.phi, view.positions, view.f_t, view.tau, p.mu, c0=c0)
            gamma = r.gamma
        else:
            solve = robust_cor if p.solver == CorSolver.ROBUST else paper_cor
            extra = {"gain": p.paper_gain} if p.solver == CorSolver.PAPER else {}
            r = solve(view.phi, view.positions, view.f_t, view.tau, p.mu, c0=c0, **extra)
            gamma = r.ratio
        if r.p_c is not None:
            self._last_pc = r.p_c
        usable = r.status.usable
        if not usable:
            ctx.count(f"cor.{r.status.value}")
        ctx.publish("cor", Cor(
            case=r.case.value, p_c=np.array(r.p_c if r.p_c is not None else (0.0, 0.0)),
            torque_capacity=r.torque_capacity, load_torque=r.load_torque, gamma=float(gamma),
            iterations=r.iterations, residual=float(r.residual), converged=usable, status=r.status.value,
        ), stamp_ns=stamp, sources=msg.header.sources)
