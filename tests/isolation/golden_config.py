"""What the golden recordings under ``tests/isolation/golden/`` are made of.

One :class:`Golden` per file: a short scene that slips early (built from a shipped
scene with :func:`dataclasses.replace`) and the parameters of every processing node,
as in the paper-scene launch files (``launch/files/fig15.toml``, ``fig12.toml`` over
``stack.toml``). ``make_golden.py`` runs the stack on the scene with these
parameters; ``test_golden.py`` builds each node from the same parameters with
:func:`build_node`, so recording and replay cannot drift apart.

The recordings start at simulated time 0, with the stack: every node's state
(warm starts, the slip latch, the grip governor, the newest tactile frame) is then
a function of the recorded inputs alone, so a replay from the first frame reproduces
every output.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from slipstack.lib.rig.scene import DisturbanceSpec, Scene, Segment
from slipstack.nodes.cor_estimator import CorEstimator, CorParams
from slipstack.nodes.fusion import Fusion, FusionParams
from slipstack.nodes.grip_controller import GripController, GripControllerParams
from slipstack.launch.lockstep import StackConfig, load_scene_by_name
from slipstack.nodes.runtime.node import Node
from slipstack.nodes.rig import with_rates
from slipstack.nodes.slip_detector import SlipDetector, SlipDetectorParams

__all__ = ["GOLDEN_DIR", "Golden", "GOLDENS", "NODES", "build_node"]

GOLDEN_DIR = Path(__file__).parent / "golden"

# Sensor rates of stack.toml (ft_rate_hz, tactile_rate_hz, truth_rate_hz), Hz.
FT_HZ, TACTILE_HZ, TRUTH_HZ = 500.0, 250.0, 250.0
MU, DELTA, F_MAX_N = 0.45, 0.1, 20.0
GAMMA_RELEASE = 0.76  # pinned: the goldens were recorded with it (the default now comes from the material)
ONSET_FRAMES = 1  # pinned: the goldens were recorded when one frame in the band raised the flag
GAMMA_RESUME = math.nan  # pinned: recorded when any frame at the release level restarted the dwell


@dataclass(frozen=True)
class Golden:
    """One golden recording: scene recipe and node parameters.

    base: shipped scene it is cut from; duration_s: simulated length (s);
    segments: the disturbance profile replacing the base scene's (channels
    ``(f_x N, f_y N, τ N·m)``); the ``*_params`` dicts are the nodes' own parameters.
    """

    name: str
    base: str
    duration_s: float
    segments: tuple[Segment, ...]
    tactile: bool
    fusion: dict[str, Any]
    slip: dict[str, Any]
    grip: dict[str, Any]
    cor: dict[str, Any]

    @property
    def path(self) -> Path:
        return GOLDEN_DIR / f"{self.name}.mcap"

    def scene(self) -> Scene:
        """The base scene, shortened, with the early-slip disturbance and stack.toml's rates."""
        base = load_scene_by_name(self.base)
        dist: DisturbanceSpec = replace(base.disturbance, segments=self.segments)
        return with_rates(replace(base, duration_s=self.duration_s, disturbance=dist), FT_HZ, TACTILE_HZ, TRUTH_HZ)

    def stack_config(self) -> StackConfig:
        return StackConfig(controller=True, tactile=self.tactile, grip=self.grip, slip=self.slip,
                           cor=self.cor, fusion=self.fusion)


GOLDENS: tuple[Golden, ...] = (
    # fig15's tilted offset contact, pulled 15 mm off centre: combined slip at ~0.2 s,
    # caught by law (14) on the exact test.
    Golden(
        name="tactile14",
        base="fig15",
        duration_s=0.3,
        segments=(Segment("hold", 0.03), Segment("ramp", 0.1, target=(0.0, 1.8, 0.0)), Segment("hold", 0.07),
                  Segment("ramp", 0.1, target=(0.0, 0.0, 0.0))),
        tactile=True,
        fusion={"use_tactile": True},
        slip={"method": "exact", "mu": MU, "beta_m": 0.0, "delta": DELTA, "gamma_release": GAMMA_RELEASE,
              "gamma_resume": GAMMA_RESUME, "onset_frames": ONSET_FRAMES},
        grip={"law": "tactile14", "mu": MU, "beta_m": 0.0, "f_nom_n": 2.0, "f_max_n": F_MAX_N, "delta": DELTA, "gamma_release": GAMMA_RELEASE},
        cor={"solver": "exact", "mu": MU, "per_tactile_frame": True},
    ),
    # fig12's flat object, a step of force and torque at its centre (faster than the
    # grip can follow), F/T sensor only: the linear limit-surface test and the σ
    # variant of law (13).
    Golden(
        name="ft13_sigma",
        base="fig12",
        duration_s=0.5,
        segments=(Segment("hold", 0.1), Segment("step", 0.4, target=(0.0, 2.0, 0.01))),
        tactile=False,
        fusion={"use_tactile": False},
        slip={"method": "linear_ls", "mu": MU, "beta_m": 0.00344, "delta": DELTA, "gamma_release": GAMMA_RELEASE,
              "gamma_resume": GAMMA_RESUME, "onset_frames": ONSET_FRAMES},
        grip={"law": "ft13_sigma", "mu": MU, "beta_m": 0.00344, "f_nom_n": 2.0, "f_max_n": F_MAX_N, "delta": DELTA, "gamma_release": GAMMA_RELEASE},
        cor={},
    ),
)

NODES = ("fusion", "cor_estimator", "slip_detector", "grip_controller")


def build_node(golden: Golden, node: str) -> Node:
    """A fresh node of type ``node`` (one of :data:`NODES`) with ``golden``'s parameters."""
    if node == "fusion":
        return Fusion(FusionParams(**golden.fusion))
    if node == "cor_estimator":
        return CorEstimator(CorParams(**golden.cor))
    if node == "slip_detector":
        return SlipDetector(SlipDetectorParams(**golden.slip))
    if node == "grip_controller":
        return GripController(GripControllerParams(**golden.grip))
    raise ValueError(f"unknown node {node!r}; one of {NODES}")
