"""What the golden recordings under ``tests/isolation/golden/`` are made of.

More in docs/modules.md, `tests/isolation/golden_config.py`.
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from slipstack.launch.launch_file import NodeEntry, load_launch_file
from slipstack.nodes.runtime.node import Node

__all__ = ["GOLDEN_DIR", "Golden", "GOLDENS", "NODES", "build_node"]

GOLDEN_DIR = Path(__file__).parent / "golden"
NODES = ("fusion", "cor_estimator", "slip_detector", "grip_controller")


@dataclass(frozen=True)
class Golden:
    """One golden recording: ``name`` (``golden/<name>.mcap`` and ``.scene.toml``) and the
    shipped launch file it runs."""

    name: str
    launch: str

    @property
    def path(self) -> Path:
        return GOLDEN_DIR / f"{self.name}.mcap"

    @property
    def scene_path(self) -> Path:
        return GOLDEN_DIR / f"{self.name}.scene.toml"

    def launch_args(self, recording: Path | None = None) -> dict[str, str]:
        """The launch arguments of the recording run (every topic recorded to ``recording``)."""
        args = {"scene": str(self.scene_path), "monitor": "false"}
        if recording is None:
            return {**args, "record": "false"}
        return {**args, "recording": str(recording), "record_topics": "[]"}

    def entry(self, node: str) -> NodeEntry:
        """The launch file's entry of ``node`` (one of :data:`NODES`)."""
        return _entries(self)[node]

    @property
    def tactile(self) -> bool:
        return "tactile_driver" in _entries(self)

    def params(self, node: str) -> dict[str, Any]:
        """``node``'s parameters as the node resolves them (material values filled in)."""
        return dataclasses.asdict(build_node(self, node).params)

    @property
    def slip(self) -> dict[str, Any]:
        """The slip detector's settings: method, μ, β, band and release level."""
        p = self.params("slip_detector")
        return {k: p[k] for k in ("method", "mu", "beta_m", "delta", "gamma_release", "release_ms", "pool")}

    @property
    def grip(self) -> dict[str, Any]:
        return self.params("grip_controller")

    @property
    def cor(self) -> dict[str, Any]:
        return self.params("cor_estimator")


@functools.cache
def _entries(golden: Golden) -> dict[str, NodeEntry]:
    launch = load_launch_file(golden.launch, golden.launch_args(), builtins={"run_dir": "/nonexistent"})
    return {e.name: e for e in launch.nodes}


GOLDENS: tuple[Golden, ...] = (
    # fig15's tilted offset contact pulled off centre: combined slip, caught by law (14) on the exact test.
    Golden(name="tactile14", launch="fig15"),
    # fig12's flat object, a step of force and torque (faster than the grip can follow), F/T only:
    # the linear limit-surface test and the σ variant of law (13).
    Golden(name="ft13_sigma", launch="fig12"),
)


def build_node(golden: Golden, node: str) -> Node:
    """A fresh node of type ``node`` (one of :data:`NODES`) with ``golden``'s launch-file parameters."""
    if node not in NODES:
        raise ValueError(f"unknown node {node!r}; one of {NODES}")
    return golden.entry(node).instance()
