"""fusion: pairs ``ft/wrench`` with the newest ``tactile/frame`` into ``contact`` (docs/safety.md).

More in docs/modules.md, `nodes/fusion.py`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from slipstack.lib.fusion import (FusionThresholds, PressureShape, compile_kernels, ft_understates_pad, fuse_shape,
                                  pressure_shape)
from slipstack.lib.pad import PadGeometry
from slipstack.lib.status import SolverStatus
from slipstack.messages import STATUS_OK, TACTILE_PAIRING, Contact, TactileFrame, Wrench
from slipstack.messages.types import MAX_EARLIER_SAMPLES, SAMPLE_NO_CONTACT, SAMPLE_OK, SAMPLE_UNUSABLE
from slipstack.nodes.runtime.node import Context, Input, Node, Output

__all__ = ["Fusion", "FusionParams", "BATCH_DEPTH", "SAMPLES_PER_CONTACT"]

SAMPLES_PER_CONTACT = MAX_EARLIER_SAMPLES + 1
"""F/T samples one contact carries: its newest and the earlier ones."""
BATCH_DEPTH = 1000
"""F/T samples fusion takes per wake-up, at most (the input socket's high-water mark):
a backlog after a stall (1 s at 1 kHz, 0.14 s at 7 kHz) is examined, not skipped, as
consecutive contacts of :data:`SAMPLES_PER_CONTACT` samples."""

_USABLE_AS_OK = (STATUS_OK, SolverStatus.CLIPPED_INPUT.value)
"""Fusion outcomes a contact reports as ``ok`` (clipped taxels are counted, not flagged)."""
_JUDGED_ON_THE_PAD = (*_USABLE_AS_OK, SolverStatus.NO_CONTACT.value)
"""Fusion outcomes after which the F/T reading is checked against the pressed pad."""
_SAMPLE_CODES = {STATUS_OK: SAMPLE_OK, SolverStatus.NO_CONTACT.value: SAMPLE_NO_CONTACT}
"""``Contact.earlier_status`` of a sample by its own contact's status (any other: unusable)."""


@dataclass(frozen=True)
class FusionParams:
    noise_floor_pa: float = field(default=2000.0, metadata={"help": "taxel in contact above this pressure (Pa)"})
    min_normal_force_n: float = field(default=0.05, metadata={"help": "contact needs f_n above this (N)"})
    max_pair_age_ms: float = field(default=10.0, metadata={"help": "oldest tactile frame paired with a wrench (ms)"})
    use_tactile: bool = field(default=True, metadata={"help": "false: F/T-only contacts (scenes without tactile)"})
    ft_plausibility_ratio: float = field(default=3.0, metadata={
        "help": "contact is 'implausible' when the pad's force exceeds this times the F/T normal force; 0: off"})
    ft_plausibility_min_n: float = field(default=0.5, metadata={
        "help": "the plausibility check applies once the pad's own force exceeds this (N)"})


class Fusion(Node):
    """Local normal force per taxel from tactile shape and F/T magnitude."""

    name = "fusion"
    inputs = {
        "wrench": Input("ft/wrench", Wrench, policy="batch", depth=BATCH_DEPTH),
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

    def start(self, ctx: Context) -> None:
        compile_kernels()  # before the node reports ready, so its first tactile frame runs at full speed

    def on_tactile(self, msg: TactileFrame, ctx: Context) -> None:
        self.tactile = msg
        self._shape = None

    def on_wrench(self, msgs: tuple[Wrench, ...], ctx: Context) -> None:
        sensor_frame = len(msgs) - [w.frame for w in msgs].count("pad")
        if sensor_frame:
            ctx.count("fusion.sensor_frame_wrenches", sensor_frame)  # the driver should apply the mount transform
        for run in self._pairing_runs(msgs):
            for start in range(0, len(run), SAMPLES_PER_CONTACT):  # a backlog: several contacts, oldest first
                self._publish_contact(run[start:start + SAMPLES_PER_CONTACT], ctx)

    def _pairing_runs(self, msgs: tuple[Wrench, ...]) -> list[tuple[Wrench, ...]]:
        """``msgs`` cut, in order, into runs of consecutive samples that the tactile frame
        pairs with alike (inside or outside ``max_pair_age_ms``), so a contact never
        carries a sample its frame would not be paired with (a backlog spans more than
        the window)."""
        if len(msgs) == 1:  # the usual wake-up: one sample, one run
            return [msgs]
        runs: list[tuple[Wrench, ...]] = []
        start = 0
        paired = [self._tactile_status(w.header.stamp_ns) == STATUS_OK for w in msgs]
        for k in range(1, len(msgs) + 1):
            if k == len(msgs) or paired[k] != paired[start]:
                runs.append(msgs[start:k])
                start = k
        return runs

    def _publish_contact(self, msgs: tuple[Wrench, ...], ctx: Context) -> None:
        """One contact for the newest of ``msgs`` (at most :data:`SAMPLES_PER_CONTACT`)
        carrying the earlier ones."""
        msg = msgs[-1]
        stamp = msg.header.stamp_ns
        tactile_status = self._tactile_status(stamp)
        if tactile_status == STATUS_OK:
            t = self.tactile
            contact = self._fused(msg, t, ctx)
            sources = {"ft": stamp, "tactile": t.header.stamp_ns}
        else:
            if self.params.use_tactile:
                ctx.count(f"fusion.unpaired_wrenches.{tactile_status}")
            contact = self._ft_only(msg, tactile_status)
            sources = {"ft": stamp}
        if len(msgs) > 1:
            contact = self._with_earlier(contact, msgs[:-1], tactile_status == STATUS_OK, ctx)
            sources["ft_oldest"] = msgs[0].header.stamp_ns
        ctx.count("fusion.samples", len(msgs))
        ctx.publish("contact", contact, stamp_ns=stamp, sources=sources)

    def _tactile_status(self, wrench_stamp_ns: int) -> str:
        """``ok`` when the newest tactile frame can be paired with this wrench, else why not."""
        t = self.tactile
        if not self.params.use_tactile:
            return "off"
        if t is None:
            return "none"
        if t.status != STATUS_OK:
            return t.status if t.status in TACTILE_PAIRING else "fault"
        if abs(wrench_stamp_ns - t.header.stamp_ns) > self.params.max_pair_age_ms * 1e6:
            return "unpaired"
        return STATUS_OK

    def _fused(self, w: Wrench, t: TactileFrame, ctx: Context) -> Contact:
        pad = _pad(t.rows, t.cols, t.pitch_m)
        if self._shape is None:  # the tactile half, once per frame
            self._shape = pressure_shape(t.pressure_pa, pad, self.thresholds, saturated=t.saturated)
            if self._shape.n_nonfinite or self._shape.n_negative:  # bad taxels were clipped to 0: count why
                ctx.count("fusion.nonfinite_taxels", self._shape.n_nonfinite)
                ctx.count("fusion.negative_taxels", self._shape.n_negative)
        r = fuse_shape(self._shape, w.force, w.torque, pad, self.thresholds,
                       tactile_stamp_ns=t.header.stamp_ns, wrench_stamp_ns=w.header.stamp_ns)
        status = w.status if w.status != STATUS_OK else r.status.value
        p = self.params
        if status in _JUDGED_ON_THE_PAD and ft_understates_pad(
                self._shape, pad, -float(w.force[2]), ratio=p.ft_plausibility_ratio, min_pad_force_n=p.ft_plausibility_min_n):
            ctx.count("fusion.implausible_ft")
            status = "implausible"
        return Contact(  # the result's arrays are float64 (the mask bool) and read-only: passed on as they are
            rows=t.rows, cols=t.cols, pitch_m=t.pitch_m, phi=r.phi, f_n=r.f_n, f_t=r.f_t, tau=r.tau, cop=r.cop,
            area_m2=r.contact_area_m2, mask=r.mask,
            pair_offset_ns=t.header.stamp_ns - w.header.stamp_ns, has_tactile=True,
            status=STATUS_OK if status in _USABLE_AS_OK else status,
        )

    def _with_earlier(self, contact: Contact, earlier: tuple[Wrench, ...], paired: bool, ctx: Context) -> Contact:
        """``contact`` (the newest sample's) carrying the loads of the ``earlier`` samples of
        its batch in the pad frame, each judged usable as its own contact would be, and the
        first unusable one's status when the newest is usable (class docstring)."""
        force = np.array([w.force for w in earlier])
        f_n = -force[:, 2]
        statuses = [self._sample_status(w, f, paired, ctx) for w, f in zip(earlier, f_n.tolist())]
        codes = np.array([_SAMPLE_CODES.get(s, SAMPLE_UNUSABLE) for s in statuses], dtype=np.uint8)
        status = contact.status
        if status in _SAMPLE_CODES and (codes == SAMPLE_UNUSABLE).any():
            status = statuses[int(np.argmax(codes == SAMPLE_UNUSABLE))]
        return dataclasses.replace(
            contact, status=status, earlier_samples=len(earlier),
            earlier_stamp_ns=np.array([w.header.stamp_ns for w in earlier], dtype=np.int64),
            earlier_f_n=np.maximum(f_n, 0.0), earlier_f_tx=force[:, 0].copy(), earlier_f_ty=force[:, 1].copy(),
            earlier_tau=np.array([float(w.torque[2]) for w in earlier]), earlier_status=codes)

    def _sample_status(self, w: Wrench, f_n: float, paired: bool, ctx: Context) -> str:
        """The status an earlier sample's own contact would carry (normal force ``f_n``, N)."""
        if w.status != STATUS_OK:
            return w.status
        p = self.params
        if paired and self._shape is not None and ft_understates_pad(
                self._shape, _pad(self.tactile.rows, self.tactile.cols, self.tactile.pitch_m), f_n,
                ratio=p.ft_plausibility_ratio, min_pad_force_n=p.ft_plausibility_min_n):
            ctx.count("fusion.implausible_ft")
            return "implausible"
        return STATUS_OK if f_n > p.min_normal_force_n else SolverStatus.NO_CONTACT.value

    def _ft_only(self, w: Wrench, tactile_status: str) -> Contact:
        f_n = -float(w.force[2])
        in_contact = f_n > self.params.min_normal_force_n
        status = w.status if w.status != STATUS_OK else (STATUS_OK if in_contact else SolverStatus.NO_CONTACT.value)
        return Contact(
            rows=0, cols=0, pitch_m=0.0, phi=np.zeros(0), f_n=max(f_n, 0.0), f_t=np.asarray(w.force[:2], dtype=float),
            tau=float(w.torque[2]), cop=np.zeros(2), area_m2=0.0, mask=np.zeros(0, dtype=bool),
            has_tactile=False, tactile_status=tactile_status, status=status,
        )


@lru_cache(maxsize=8)
def _pad(rows: int, cols: int, pitch_m: float) -> PadGeometry:
    """The pad geometry of a tactile frame's shape; a few geometries cached (bounded)."""
    return PadGeometry(rows, cols, pitch_m)
