"""grasp_planner: one ``grasp/goal`` at a given time of the scene, as a task planner would send it.

The simulated gripper's pivot and slide scenes run unattended with it: it publishes its goal
once ``at_s`` seconds after the scene started (the first ``rig/truth`` sample). On hardware a
planner of your own, or a person (``slipstack topic pub grasp/goal "{mode: pivot, ...}"``),
sends the goals instead.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from slipstack.lib.errors import ConfigError
from slipstack.messages import GraspGoal, RigTruth
from slipstack.messages.grasp import GRASP_MODES
from slipstack.nodes.runtime.node import Context, Input, Node, Output

__all__ = ["GraspPlanner", "GraspPlannerParams"]


@dataclass(frozen=True)
class GraspPlannerParams:
    mode: str = field(default="hold", metadata={"help": f"the goal's mode: one of {GRASP_MODES}"})
    at_s: float = field(default=1.5, metadata={"help": "send it this long after the scene started (s)"})
    angle_deg: float = field(default=0.0, metadata={"help": "pivot: turn by this much (deg)"})
    rate_deg_s: float = field(default=0.0, metadata={"help": "pivot: at this rate (deg/s)"})
    distance_mm: float = field(default=0.0, metadata={"help": "slide: move by this much (mm)"})
    speed_mm_s: float = field(default=0.0, metadata={"help": "slide: at this speed (mm/s)"})

    def __post_init__(self) -> None:
        if self.mode not in GRASP_MODES:
            raise ConfigError(f"grasp_planner: mode must be one of {', '.join(GRASP_MODES)}, got {self.mode!r}")
        if not (math.isfinite(self.at_s) and self.at_s >= 0.0):
            raise ConfigError(f"grasp_planner: at_s must be a time >= 0 s, got {self.at_s!r}")


class GraspPlanner(Node):
    """Publishes its one goal at ``at_s`` of the scene."""

    name = "grasp_planner"
    inputs = {"truth": Input("rig/truth", RigTruth)}
    outputs = {"goal": Output("grasp/goal", GraspGoal)}
    Params = GraspPlannerParams

    def __init__(self, params: GraspPlannerParams | None = None) -> None:
        super().__init__(params)
        p = self.params
        self.goal = GraspGoal(mode=p.mode, angle_rad=math.radians(p.angle_deg), rate_rad_s=math.radians(p.rate_deg_s),
                              distance_m=p.distance_mm * 1e-3, speed_m_s=p.speed_mm_s * 1e-3)
        self._t0: int | None = None
        self.sent = False

    def on_truth(self, msg: RigTruth, ctx: Context) -> None:
        stamp = msg.header.stamp_ns
        if self._t0 is None:
            self._t0 = stamp
        if not self.sent and stamp - self._t0 >= round(self.params.at_s * 1e9):
            self.sent = True
            ctx.publish("goal", self.goal, stamp_ns=stamp)
            ctx.log(f"goal sent at {(stamp - self._t0) / 1e9:.3f} s of the scene: {self.params.mode}")
