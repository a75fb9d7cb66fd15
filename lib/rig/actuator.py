"""Finger actuator: commanded normal force → applied normal force ``f_n`` (N)."""

from __future__ import annotations

import math

from slipstack.lib.rig.scene import FingerSpec

__all__ = ["CommandWatchdog", "FingerActuator"]


class FingerActuator:
    """First-order lag with rate limit and saturation.

    ``ḟ = ω_b (f_cmd − f)``, ``ω_b = 2π·bandwidth_hz``, discretised exactly over a
    step (``Δf = (f_cmd − f)(1 − e^{−ω_b dt})``), then ``|Δf| ≤ rate·dt`` and
    ``f, f_cmd ∈ [0, f_max]``.

    Args:
        spec: the finger parameters; the applied force and the command start at
            ``f_initial_N``.
    """

    def __init__(self, spec: FingerSpec) -> None:
        self._spec = spec
        self.force = spec.f_initial_N
        self.command_N = spec.f_initial_N
        self.rejected = 0

    def command(self, f_n_N: float) -> bool:
        """Set the commanded normal force (N), clipped to ``[0, f_max]``.

        Returns:
            False (and the command is ignored and counted in ``rejected``) when the
            value is not a finite number; True otherwise.
        """
        try:
            value = float(f_n_N)
        except (TypeError, ValueError):
            value = math.nan
        if not math.isfinite(value):
            self.rejected += 1
            return False
        self.command_N = min(max(value, 0.0), self._spec.f_max_N)
        return True

    def step(self, dt_s: float) -> float:
        """Advance by ``dt_s`` seconds; returns the applied normal force (N)."""
        if self.force != self.command_N:
            spec = self._spec
            gain = 1.0 - math.exp(-2.0 * math.pi * spec.bandwidth_hz * dt_s)
            limit = spec.rate_N_per_s * dt_s
            error = self.command_N - self.force
            # Snap the last nanonewton so the lag ends (the shape cache can then rest).
            delta = error if abs(error) < 1e-9 else min(max(error * gain, -limit), limit)
            self.force = min(max(self.force + delta, 0.0), spec.f_max_N)
        return self.force


class CommandWatchdog:
    """The finger's own guard against a silent controller (plant side, docs/safety.md).

    Once a first command has arrived, a gap of more than ``timeout_ns`` without one
    means the controller died or hangs. The finger then never releases: it holds its
    last command and, with ``safe_grip_n`` above it, raises the command towards
    ``safe_grip_n`` at ``rise_n_per_s`` (the load may grow while nobody watches). A new
    command ends the watchdog's hold. Times are integer ns on one clock; forces in N.
    """

    def __init__(self, timeout_ns: int, safe_grip_n: float = 0.0, rise_n_per_s: float = 10.0) -> None:
        if timeout_ns < 0 or not (math.isfinite(safe_grip_n) and safe_grip_n >= 0.0) or not rise_n_per_s > 0.0:
            raise ValueError("command watchdog: timeout_ns >= 0, safe_grip_n >= 0 N and rise_n_per_s > 0 N/s")
        self.timeout_ns = timeout_ns
        self.safe_grip_n = safe_grip_n
        self.rise_n_per_s = rise_n_per_s
        self._last_command_ns: int | None = None
        self._last_step_ns: int | None = None
        self.expired = False

    def commanded(self, now_ns: int) -> None:
        """A command arrived at ``now_ns``."""
        self._last_command_ns = now_ns
        self.expired = False

    def due_ns(self, period_ns: int) -> int | None:
        """When :meth:`step` may next change the command (ns): just past the timeout after the
        last command, or, once expired, ``period_ns`` after the last step; None before the
        first command or with the watchdog off."""
        if self.timeout_ns == 0 or self._last_command_ns is None:
            return None
        if self.expired:
            return (self._last_step_ns if self._last_step_ns is not None else self._last_command_ns) + period_ns
        return self._last_command_ns + self.timeout_ns + 1

    def step(self, now_ns: int, command_n: float) -> float | None:
        """The command the finger should follow now (N), or ``None`` to keep ``command_n``.

        ``None`` while commands arrive in time (or before the first one, or with
        ``timeout_ns = 0``, which disables the watchdog).
        """
        last_step, self._last_step_ns = self._last_step_ns, now_ns
        if self.timeout_ns == 0 or self._last_command_ns is None:
            return None
        if now_ns - self._last_command_ns <= self.timeout_ns:
            return None
        self.expired = True
        dt_s = 0.0 if last_step is None else max(now_ns - last_step, 0) * 1e-9
        if command_n >= self.safe_grip_n:
            return command_n
        return min(command_n + self.rise_n_per_s * dt_s, self.safe_grip_n)
