"""fusion: pairs ``ft/wrench`` with the newest ``tactile/frame`` into ``contact`` (MATH.md §2).

Every wrench (the faster stream) produces one ``contact``: with the newest tactile
frame if it is younger than ``max_pair_age_ms``, otherwise an F/T-only contact
(``has_tactile`` false). ``header.sources`` carries both stamps and
``pair_offset_ns`` the tactile minus F/T stamp, so every consumer knows which
samples were paired and how old they were. A stale or disconnected sensor passes its
status on, so the grip controller can hold.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from slipstack.lib.fusion import FusionThresholds, PressureShape, fuse_shape, pressure_shape
from slipstack.lib.pad import PadGeometry
from slipstack.messages import STATUS_OK, Contact, TactileFrame, Wrench
from slipstack.nodes.node import Context, Input, Node, Output

__all__ = ["Fusion", "FusionParams"]


@dataclass(frozen=True)
class FusionParams:
    noise_floor_pa: float = field(default=2000.0, metadata={"help": "taxel in contact above this pressure (Pa)"})
    min_normal_force_n: float = field(default=0.05, metadata={"help": "contact needs f_n above this (N)"})
    max_pair_age_ms: float = field(default=10.0, metadata={"help": "oldest tactile frame paired with a wrench (ms)"})
    use_tactile: bool = field(default=True, metadata={"help": "false: F/T-only contacts (scenes without tactile)"})


class Fusion(Node):
    """Local normal force per taxel from tactile shape and F/T magnitude."""

    name = "fusion"
    inputs = {
        "wrench": Input("ft/wrench", Wrench),
        "tactile": Input("tactile/frame", TactileFrame),
    }
    outputs = {"contact": Output("contact", Contact)}
    Params = FusionParams

    def __init__(self, params: FusionParams | None = None) -> None:
        super().__init__(params)
        p = self.params
        self.thresholds = FusionThresholds(noise_floor_pa=p.noise_floor_pa, min_normal_force_n=p.min_normal_force_n)
        self.tactile: TactileFrame | None = None
        self._shape: PressureShape | None = None  # of self.tactile, computed at its first pairing
        self._pads: dict[tuple[int, int, float], PadGeometry] = {}

    def on_tactile(self, msg: TactileFrame, ctx: Context) -> None:
        self.tactile = msg
        self._shape = None

    def on_wrench(self, msg: Wrench, ctx: Context) -> None:
        stamp = msg.header.stamp_ns
        if msg.frame != "pad":
            ctx.count("fusion.sensor_frame_wrenches")  # the driver should apply the mount transform
        t = self.tactile
        fresh = (
            self.params.use_tactile and t is not None and t.status == STATUS_OK
            and abs(stamp - t.header.stamp_ns) <= self.params.max_pair_age_ms * 1e6
        )
        if fresh:
            contact = self._fused(msg, t, ctx)
            sources = {"ft": stamp, "tactile": t.header.stamp_ns}
        else:
            if self.params.use_tactile:
                ctx.count("fusion.unpaired_wrenches")
            contact = self._ft_only(msg)
            sources = {"ft": stamp}
        ctx.publish("contact", contact, stamp_ns=stamp, sources=sources)

    def _fused(self, w: Wrench, t: TactileFrame, ctx: Context) -> Contact:
        key = (t.rows, t.cols, t.pitch_m)
        pad = self._pads.get(key) or self._pads.setdefault(key, PadGeometry(*key))
        if self._shape is None:  # the tactile half, once per frame
            self._shape = pressure_shape(t.pressure_pa, pad, self.thresholds, saturated=t.saturated)
            if self._shape.n_nonfinite or self._shape.n_negative:  # bad taxels were clipped to 0: count why
                ctx.count("fusion.nonfinite_taxels", self._shape.n_nonfinite)
                ctx.count("fusion.negative_taxels", self._shape.n_negative)
        r = fuse_shape(self._shape, w.force, w.torque, pad, self.thresholds,
                       tactile_stamp_ns=t.header.stamp_ns, wrench_stamp_ns=w.header.stamp_ns)
        status = w.status if w.status != STATUS_OK else r.status.value
        return Contact(
            rows=t.rows, cols=t.cols, pitch_m=t.pitch_m, phi=np.asarray(r.phi, dtype=float), f_n=r.f_n,
            f_t=np.asarray(r.f_t, dtype=float), tau=r.tau, cop=np.asarray(r.cop, dtype=float),
            area_m2=r.contact_area_m2, mask=np.asarray(r.mask, dtype=bool),
            pair_offset_ns=t.header.stamp_ns - w.header.stamp_ns, has_tactile=True,
            status="ok" if status in ("ok", "clipped_input") else status,
        )

    def _ft_only(self, w: Wrench) -> Contact:
        f_n = -float(w.force[2])
        status = w.status if w.status != STATUS_OK else ("ok" if f_n > self.params.min_normal_force_n else "no_contact")
        return Contact(
            rows=0, cols=0, pitch_m=0.0, phi=np.zeros(0), f_n=max(f_n, 0.0), f_t=np.asarray(w.force[:2], dtype=float),
            tau=float(w.torque[2]), cop=np.zeros(2), area_m2=0.0, mask=np.zeros(0, dtype=bool),
            has_tactile=False, status=status,
        )
