"""Finger actuator: commanded normal force → applied normal force ``f_n`` (N)."""

from __future__ import annotations

import math

from slipstack.lib.rig.scene import FingerSpec

__all__ = ["FingerActuator"]


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
