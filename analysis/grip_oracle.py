"""The oracle's grip over a run: the least normal force that holds the true load, per truth sample.

At each sample of the rig's truth (object pose, applied normal force, the load the
contact transmits) the pressure is the scene's model at that force and pose, and the
oracle is the least ``f_n`` with which that pressure holds the true load with the
contact's ``μ_s`` (``lib/oracle.py``, docs/math.md §4.1): the fixed point of
``γ(φ(f))·f`` for a force-dependent (Hertzian) shape, and, for comparison, the
frozen-shape answer ``γ·f_applied``. Used by ``tests/bench/bench_grip_economy.py`` and
the grip-economy figure of ``slipstack reproduce``. Forces in N, the pad frame ``F``. On
the simulated gripper (:func:`grasp_oracle_series`) the least squeeze holds both fingers'
true loads, each with its own contact (docs/math.md §9).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from slipstack.lib.oracle import least_holding_force, oracle_normal_force
from slipstack.lib.rig.contact import PressureModel
from slipstack.lib.pad import PadGeometry
from slipstack.lib.rig.scene import ContactSpec, Scene

__all__ = ["OracleSeries", "oracle_series", "grasp_oracle_series"]


@dataclass(frozen=True)
class OracleSeries:
    """The oracle per truth sample (N; NaN where no usable answer: no contact, solver failure).

    least: the fixed point ``γ(φ(f*)) = 1``; frozen: ``γ·f_applied`` with the pressure
    shape frozen at the applied force.
    """

    least: np.ndarray
    frozen: np.ndarray


def oracle_series(scene: Scene, x_m: np.ndarray, y_m: np.ndarray, theta_rad: np.ndarray,
                  f_n_applied: np.ndarray, load_f_t: np.ndarray, load_tau: np.ndarray) -> OracleSeries:
    """The oracle at each truth sample of a run of ``scene``.

    Args:
        scene: the scene the run simulated (its contact, pad and initial pose).
        x_m, y_m, theta_rad: (K,) the object's true pose (m, m, rad).
        f_n_applied: (K,) the normal force the finger applied, N.
        load_f_t: (K, 2) the tangential load the contact transmits, N, in F.
        load_tau: (K,) the torque it transmits about z through the pad origin, N·m.
    """
    return _series(scene.contact, scene.pad, scene.object.pose, x_m, y_m, theta_rad, f_n_applied, load_f_t, load_tau)


def grasp_oracle_series(scene: Scene, x_m: np.ndarray, y_m: np.ndarray, theta_rad: np.ndarray,
                        f_n_applied: np.ndarray, finger_f_t: tuple[np.ndarray, np.ndarray],
                        finger_tau: tuple[np.ndarray, np.ndarray]) -> OracleSeries:
    """The least squeeze that holds both fingers' true loads at each truth sample of a run of
    the gripper ``scene``: the larger of the two fingers' oracles (a contact may not slip
    while the other holds: docs/math.md §9).

    Args:
        scene: a gripper scene (``[gripper]``).
        x_m, y_m, theta_rad: (K,) the object's true pose in finger 0's frame ``F``.
        f_n_applied: (K,) the squeeze, N.
        finger_f_t: per finger (K, 2) the tangential load its contact transmits, N, in
            its own pad frame (``rig/grasp``); finger_tau: per finger (K,) N·m.
    """
    x1 = -np.asarray(x_m)  # the pose in finger 1's frame: x → −x, the angle's sense reversed
    pose0 = scene.object.pose
    pose1 = (-pose0[0], pose0[1], -pose0[2])
    fingers = [
        _series(scene.contact, scene.pad, pose0, x_m, y_m, theta_rad, f_n_applied, finger_f_t[0], finger_tau[0]),
        _series(scene.gripper.contact, scene.pad, pose1, x1, y_m, -np.asarray(theta_rad), f_n_applied, finger_f_t[1],
                finger_tau[1]),
    ]
    return OracleSeries(np.fmax(fingers[0].least, fingers[1].least), np.fmax(fingers[0].frozen, fingers[1].frozen))


def _series(contact: ContactSpec, pad: PadGeometry, pose0: tuple[float, float, float], x_m, y_m, theta_rad,
            f_n_applied, load_f_t, load_tau) -> OracleSeries:
    """:func:`oracle_series` of one contact (its spec, its pad frame)."""
    mu_s, positions = contact.mu_s, pad.positions
    pressure = PressureModel(contact, pad, pose0)
    least, frozen = np.full(len(x_m), math.nan), np.full(len(x_m), math.nan)
    for i in range(len(x_m)):
        origin, theta = complex(x_m[i], y_m[i]), float(theta_rad[i])

        def phi_of_f(f: float, origin: complex = origin, theta: float = theta) -> np.ndarray:
            return pressure.phi_uncached(f, origin, theta)

        first = oracle_normal_force(phi_of_f(f_n_applied[i]), positions, load_f_t[i], load_tau[i], mu_s)
        if first.usable:
            frozen[i] = first.f_n_min
        fixed = least_holding_force(phi_of_f, positions, load_f_t[i], load_tau[i], mu_s, f_n_applied[i])
        if fixed.usable:
            least[i] = fixed.f_n_min
    return OracleSeries(least, frozen)
