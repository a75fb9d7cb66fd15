"""Rotations for frame transforms given as roll, pitch, yaw angles.

Convention (the one of URDF / ROS ``rpy``): fixed-axis rotations about x by roll,
then y by pitch, then z by yaw, i.e. ``R = R_z(yaw)·R_y(pitch)·R_x(roll)``; for a
mount, ``R`` takes vectors from the child frame (the sensor S) to the parent frame
(the pad F): ``v_F = R·v_S``. A pure yaw turns the sensor's x axis by ``yaw``
towards F's y axis. The sensor-to-pad wrench transform itself is
:func:`slipstack.lib.fusion.wrench_to_pad`.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["rotation_rpy"]


def rotation_rpy(roll_rad: float, pitch_rad: float, yaw_rad: float) -> np.ndarray:
    """The (3, 3) rotation ``R_z(yaw)·R_y(pitch)·R_x(roll)`` (angles in radians)."""
    cr, sr = math.cos(roll_rad), math.sin(roll_rad)
    cp, sp = math.cos(pitch_rad), math.sin(pitch_rad)
    cy, sy = math.cos(yaw_rad), math.sin(yaw_rad)
    return np.array([
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ])
