"""The disturbance motor: force/torque or position-controlled drag on the object.

Profiles have three channels: ``(f_x N, f_y N, τ N·m)`` in wrench mode, the motor
displacement ``(x m, y m, θ rad)`` in drag mode (see
:class:`~slipstack.lib.rig.scene.Segment`). Planar vectors are complex, pad frame ``F``.
"""

from __future__ import annotations

import bisect
import math

from slipstack.lib.rig.scene import DisturbanceSpec, Segment

__all__ = ["Profile", "DisturbanceMotor"]


class Profile:
    """A piecewise profile of three channels; after the last segment the value holds.

    Args:
        segments: the sequence; each starts from the value the previous one ended on.
        initial: value before the first segment.
    """

    def __init__(self, segments: tuple[Segment, ...],
                 initial: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> None:
        self._starts: list[float] = []
        self._pieces: list[tuple[Segment, tuple[float, ...], tuple[float, ...]]] = []
        t, value = 0.0, tuple(initial)
        for seg in segments:
            end = seg.target if seg.kind in ("step", "ramp") else value
            self._starts.append(t)
            self._pieces.append((seg, value, tuple(end)))
            t += seg.duration_s
            value = tuple(end)
        self._initial = tuple(initial)
        self._final = value
        self.duration_s = t

    def value(self, t_s: float) -> tuple[float, float, float]:
        """The three channel values at time ``t_s`` (s)."""
        k = bisect.bisect_right(self._starts, t_s) - 1
        if k < 0:
            return self._initial
        seg, v0, v1 = self._pieces[k]
        tau = t_s - self._starts[k]
        if tau >= seg.duration_s:
            return self._final if k == len(self._pieces) - 1 else v1
        if seg.kind == "ramp":
            a = tau / seg.duration_s
            return (v0[0] + a * (v1[0] - v0[0]), v0[1] + a * (v1[1] - v0[1]), v0[2] + a * (v1[2] - v0[2]))
        if seg.kind == "sine":
            s = math.sin(2.0 * math.pi * seg.frequency_hz * tau)
            amp = seg.amplitude
            return (v0[0] + amp[0] * s, v0[1] + amp[1] * s, v0[2] + amp[2] * s)
        return v1


class DisturbanceMotor:
    """Applies the scene's disturbance to a point of the object.

    Args:
        spec: the disturbance parameters.
        point0: application point at t = 0 (complex, m, ``F``).
        theta0: object angle at t = 0 (rad).
    """

    def __init__(self, spec: DisturbanceSpec, point0: complex, theta0: float) -> None:
        self._spec = spec
        self.profile = Profile(spec.segments)
        self.point0 = point0
        self._theta0 = theta0

    @property
    def damping(self) -> tuple[float, float]:
        """Viscous coefficients on the point's velocity (N·s/m) and on ``ω`` (N·m·s/rad)."""
        return self._spec.damping_Ns_per_m, self._spec.damping_Nms_per_rad

    def load(self, t_s: float, point: complex, theta: float) -> tuple[complex, float]:
        """Active load at time ``t_s``: force at the point (complex N, ``F``), torque (N·m).

        Args:
            t_s: time (s).
            point: current position of the application point (complex, m).
            theta: current object angle (rad).
        """
        spec = self._spec
        a, b, c = self.profile.value(t_s)
        if spec.mode == "wrench":
            return complex(a, b), c
        return (spec.stiffness_N_per_m * (self.point0 + complex(a, b) - point),
                spec.stiffness_Nm_per_rad * (self._theta0 + c - theta))

    def encoder(self, point: complex, theta: float) -> tuple[float, float, float]:
        """The motor's position sensor (m, m, rad): displacement of the application
        point and the object angle since t = 0, as the paper's rig measures the
        object's displacement (Figs 13–15). In drag mode the motor's own position is
        the profile value, ``profile.value(t)``.
        """
        d = point - self.point0
        return (d.real, d.imag, theta - self._theta0)
