"""The two-finger grasp's messages: its goal, its state, and the simulated gripper's truth.

SI units. Finger ``i``'s loads are in its own pad frame ``F_i`` (docs/math.md §1, §9:
finger 1's frame is finger 0's turned by 180° about ``y``); the object's angle and
translation are in finger 0's frame ``F``.
"""

from __future__ import annotations

import numpy as np

from slipstack.messages.base import Message, array, bounded, message
from slipstack.messages.types import MAX_GRIP_FORCE_N, NAME_PATTERN, STATUS_OK

__all__ = ["GraspGoal", "GraspState", "GraspTruth", "GripperState", "GRASP_MODES", "MAX_PIVOT_RAD", "MAX_SLIDE_M"]

GRASP_MODES = ("hold", "pivot", "slide")
"""``hold``: the least squeeze that keeps both contacts inside their limit sets; ``pivot``:
let the load turn the object about the grasp axis; ``slide``: let it translate."""
MAX_PIVOT_RAD = 3.2
"""Largest pivot a goal may ask for (rad, a little more than half a turn)."""
MAX_SLIDE_M = 0.1
"""Largest slide a goal may ask for (m)."""


@message("slipstack/GraspGoal")
class GraspGoal(Message):
    """``grasp/goal``: what the grasp node should do now.

    mode: one of :data:`GRASP_MODES`. pivot: turn by ``angle_rad`` (≥ 0; the load
    decides the sense) at ``rate_rad_s``; slide: translate by ``distance_m`` at
    ``speed_m_s`` (the load decides the direction); then grip again. ``hold`` ends a
    mode at once. ``slipstack topic pub --once grasp/goal "{mode: pivot, angle_rad: 0.52,
    rate_rad_s: 0.52}"`` starts a 30° pivot at 30 °/s (each goal starts its mode anew:
    without ``--once``, topic pub repeats it every second).
    """

    mode: str = bounded("hold", choices=GRASP_MODES)
    angle_rad: float = bounded(0.0, ge=0.0, le=MAX_PIVOT_RAD, doc="rad")
    rate_rad_s: float = bounded(0.0, ge=0.0, le=10.0, doc="rad/s")
    distance_m: float = bounded(0.0, ge=0.0, le=MAX_SLIDE_M, doc="m")
    speed_m_s: float = bounded(0.0, ge=0.0, le=1.0, doc="m/s")


@message("slipstack/GraspState")
class GraspState(Message):
    """``grasp/state``: the grasp node's mode and what it measures.

    mode: the goal's mode now (``hold`` once a pivot or slide ended); phase: within it
    (``hold``, ``release``: lowering the squeeze until the object moves, ``track``:
    following the angle or distance, ``regrip``, ``fail-safe``); ended: why the last
    mode ended (``reached``, ``drop-guard: ...``, ``''`` while none has).
    target: the goal's angle (rad) or distance (m); progress: how far the object has
    turned (rad, signed) or moved (m) since the goal came, as the pads see it; rate:
    its rate (rad/s or m/s). translation_m: the object's translation on the pads since
    the goal came (m).
    least_n: the least squeeze that keeps both contacts inside their limit sets for the
    measured loads, ``max_i γ_i f_n,i`` (N; at most :data:`MAX_GRIP_FORCE_N`); predicted_n: the squeeze the mode's
    prediction asks for (N; the least holding squeeze in ``hold``).
    gamma (2,): each finger's load factor; f_n (2,) N: each F/T sensor's normal force;
    share (2,): each finger's share of the tangential load.
    """

    mode: str = bounded("hold", choices=GRASP_MODES)
    phase: str = bounded("hold", pattern=NAME_PATTERN, max_len=32)
    ended: str = bounded("", max_len=256)
    target: float = bounded(0.0, ge=0.0)
    progress: float = 0.0
    rate: float = 0.0
    translation_m: float = bounded(0.0, ge=0.0, doc="m")
    least_n: float = bounded(0.0, ge=0.0, le=MAX_GRIP_FORCE_N, doc="N")
    predicted_n: float = bounded(0.0, ge=0.0, le=MAX_GRIP_FORCE_N, doc="N")
    gamma: np.ndarray = array("<f8", (2,), finite=False)
    f_n: np.ndarray = array("<f8", (2,), doc="N")
    share: np.ndarray = array("<f8", (2,))
    status: str = bounded(STATUS_OK, max_len=256)


@message("slipstack/GraspTruth")
class GraspTruth(Message):
    """``rig/grasp``: the simulated gripper's truth beside ``rig/truth`` (whose loads are
    then both fingers' together, in finger 0's frame).

    f_x, f_y (2,) N, tau (2,) N·m: the load each finger's contact transmits, in that
    finger's own pad frame (what its ideal F/T sensor reads, docs/math.md §1).
    weight (2,) N: the object's weight the grasp carries now (the support's share
    taken off), in finger 0's frame; mass_kg: the object's mass now; scene: the scene the
    rig runs, as it was named to it (the oracle of ``slipstack report`` reads its contacts).
    """

    f_x: np.ndarray = array("<f8", (2,), doc="N")
    f_y: np.ndarray = array("<f8", (2,), doc="N")
    tau: np.ndarray = array("<f8", (2,), doc="N·m")
    weight: np.ndarray = array("<f8", (2,), doc="N")
    mass_kg: float = bounded(0.0, ge=0.0, doc="kg")
    scene: str = bounded("", max_len=256)


@message("slipstack/GripperState")
class GripperState(Message):
    """``gripper/state``: what the gripper driver knows of its gripper.

    force_n: the grasping force the gripper measures (N); force_limit_n: the force limit
    it last acknowledged (N); commanded_n: the squeeze the driver wants it to apply now
    (N: the newest ``grip/command``, or its watchdog's hold); state: the gripper's grasping
    state (``holding``, ``idle``, ...); watchdog: no ``grip/command`` came for the
    driver's timeout and it holds, then raises the squeeze; status: the link's (``ok``,
    ``stale``, ``disconnected``).
    """

    force_n: float = bounded(0.0, doc="N")
    force_limit_n: float = bounded(0.0, ge=0.0, le=MAX_GRIP_FORCE_N, doc="N")
    commanded_n: float = bounded(0.0, ge=0.0, le=MAX_GRIP_FORCE_N, doc="N")
    state: str = bounded("unknown", pattern=NAME_PATTERN, max_len=32)
    watchdog: bool = False
    status: str = bounded(STATUS_OK, max_len=256)
