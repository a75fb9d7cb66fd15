"""gripper_driver: ``grip/command`` → a gripper's force command (URL-chosen back-end) → ``gripper/state``.

More in docs/modules.md, `nodes/gripper_driver.py`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from slipstack.lib.errors import ConfigError
from slipstack.lib.rig.actuator import CommandWatchdog
from slipstack.lib.samples import GripperSample
from slipstack.messages import GripCommand, GripperState
from slipstack.messages.types import MAX_GRIP_FORCE_N
from slipstack.nodes.device_driver import DeviceDriver
from slipstack.nodes.runtime.node import Context, Input, Output

__all__ = ["GripperDriver", "GripperDriverParams"]


@dataclass(frozen=True)
class GripperDriverParams:
    url: str = field(metadata={"help": "gripper URL, e.g. wsg://192.168.1.20:1000?width_mm=20 (see docs/drivers.md)"})
    f_min_n: float = field(default=5.0, metadata={"help": "least squeeze sent (N; the WSG 50's least force limit)"})
    f_max_n: float = field(default=80.0, metadata={"help": "largest squeeze sent (N; the WSG 50's largest)"})
    max_command_hz: float = field(default=500.0, metadata={"help": "force commands sent per second, at most"})
    deadband_n: float = field(default=0.01, metadata={"help": "a squeeze this close to the one sent is not sent again (N)"})
    command_timeout_ms: float = field(default=100.0, metadata={
        "help": "watchdog: no grip/command for this long after the first one -> hold and raise (ms); 0: off"})
    watchdog_grip_n: float = field(default=0.0, metadata={
        "help": "the watchdog raises the squeeze towards this safe grip (N); 0: it only holds"})
    watchdog_rise_n_per_s: float = field(default=10.0, metadata={"help": "the watchdog's raise rate (N/s)"})
    stale_status_period_ms: float = field(default=10.0, metadata={
        "help": "while the gripper is stale/disconnected, republish its state with that status this often (ms)"})

    def __post_init__(self) -> None:
        if not (0.0 <= self.f_min_n <= self.f_max_n <= MAX_GRIP_FORCE_N):
            raise ConfigError(f"gripper_driver: need 0 <= f_min_n <= f_max_n <= {MAX_GRIP_FORCE_N:g} N, "
                              f"got {self.f_min_n!r}, {self.f_max_n!r}")
        if not (self.max_command_hz > 0.0 and math.isfinite(self.max_command_hz)):
            raise ConfigError(f"gripper_driver: max_command_hz must be a rate > 0, got {self.max_command_hz!r}")


class GripperDriver(DeviceDriver):
    """Tells a gripper the squeeze of ``grip/command``; publishes what it reads back."""

    name = "gripper_driver"
    kind = "gripper"
    inputs = {"grip": Input("grip/command", GripCommand)}
    outputs = {"state": Output("gripper/state", GripperState)}
    Params = GripperDriverParams

    def __init__(self, params: GripperDriverParams | None = None) -> None:
        super().__init__(params)
        p = self.params
        try:
            self.watchdog = CommandWatchdog(round(p.command_timeout_ms * 1e6), p.watchdog_grip_n,
                                            p.watchdog_rise_n_per_s)
        except ValueError as exc:
            raise ConfigError(f"gripper_driver: {exc}") from None
        self.command_period_ns = round(1e9 / p.max_command_hz)
        self.commanded_n = math.nan  # the squeeze wanted now (N)
        self._sent_n = math.nan
        self._sent_ns: int | None = None
        self._last: GripperSample | None = None

    def on_grip(self, msg: GripCommand, ctx: Context) -> None:
        now = ctx.now_ns()
        self.watchdog.commanded(now)
        self.commanded_n = min(max(float(msg.f_n_desired), self.params.f_min_n), self.params.f_max_n)
        self._command(now, ctx)

    def next_deadline_ns(self) -> int | None:
        due = super().next_deadline_ns()
        candidates = [d for d in (due, self.watchdog.due_ns(self.command_period_ns), self._resend_due()) if d is not None]
        return min(candidates) if candidates else None

    def on_deadline(self, ctx: Context) -> None:
        super().on_deadline(ctx)
        now = ctx.now_ns()
        was_expired = self.watchdog.expired
        hold = self.watchdog.step(now, self.commanded_n) if math.isfinite(self.commanded_n) else None
        if hold is not None:
            if not was_expired:
                ctx.count("gripper.watchdog")
                ctx.report_error(f"watchdog: no grip/command for {self.params.command_timeout_ms:g} ms; holding "
                                 f"{hold:.2f} N" + (f", raising towards {self.watchdog.safe_grip_n:g} N"
                                                    if self.watchdog.safe_grip_n > hold else ""))
            self.commanded_n = min(hold, self.params.f_max_n)
        self._command(now, ctx)

    def _resend_due(self) -> int | None:
        """When a wanted squeeze held back by the rate limit may go out."""
        if not math.isfinite(self.commanded_n) or abs(self.commanded_n - self._sent_n) <= self.params.deadband_n:
            return None
        return None if self._sent_ns is None else self._sent_ns + self.command_period_ns

    def _command(self, now: int, ctx: Context) -> None:
        """Send the wanted squeeze if it moved past the deadband and the rate limit allows."""
        if not math.isfinite(self.commanded_n) or abs(self.commanded_n - self._sent_n) <= self.params.deadband_n:
            return
        if self._sent_ns is not None and now - self._sent_ns < self.command_period_ns:
            return
        self.backend.set_force(self.commanded_n, now)
        self._sent_n, self._sent_ns = self.commanded_n, now
        ctx.count("gripper.commands")

    def on_sample(self, sample: GripperSample, stamp_ns: int, ctx: Context) -> None:
        self._last = sample
        self._publish("ok", stamp_ns, ctx)

    def publish_status(self, status: str, ctx: Context) -> None:
        self._publish(status, ctx.now_ns(), ctx)

    def _publish(self, status: str, stamp_ns: int, ctx: Context) -> None:
        s = self._last
        limit = self.backend.force_limit_n
        ctx.publish("state", GripperState(
            force_n=s.force_n if s is not None else 0.0,
            force_limit_n=limit if math.isfinite(limit) else 0.0,
            commanded_n=self.commanded_n if math.isfinite(self.commanded_n) else 0.0,
            state=self.backend.state, watchdog=self.watchdog.expired, status=status), stamp_ns=stamp_ns)
