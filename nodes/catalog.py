"""Which node types exist: the names ``slipstack run NODE`` and launch files use."""

from __future__ import annotations

import importlib

from slipstack.lib.errors import ConfigError
from slipstack.nodes.runtime.node import Node

__all__ = ["NODE_TYPES", "node_class"]

NODE_TYPES: dict[str, str] = {
    "wrench_source": "slipstack.nodes.demo:WrenchSource",
    "relay": "slipstack.nodes.demo:Relay",
    "sink": "slipstack.nodes.demo:Sink",
    "monitor": "slipstack.nodes.monitor:Monitor",
    "grip_controller": "slipstack.nodes.grip_controller:GripController",
    "grasp": "slipstack.nodes.grasp:Grasp",
    "grasp_planner": "slipstack.nodes.grasp_planner:GraspPlanner",
    "gripper_driver": "slipstack.nodes.gripper_driver:GripperDriver",
    "rig": "slipstack.nodes.rig:Rig",
    "fusion": "slipstack.nodes.fusion:Fusion",
    "cor_estimator": "slipstack.nodes.cor_estimator:CorEstimator",
    "slip_detector": "slipstack.nodes.slip_detector:SlipDetector",
    "recorder": "slipstack.nodes.recording.recorder:Recorder",
    "player": "slipstack.nodes.recording.player:Player",
    "ft_driver": "slipstack.nodes.ft_driver:FtDriver",
    "tactile_driver": "slipstack.nodes.tactile_driver:TactileDriver",
    "foxglove": "slipstack.nodes.foxglove_bridge:FoxgloveBridge",
    "zenoh_bridge": "slipstack.nodes.zenoh_bridge:ZenohBridge",
}


def node_class(type_name: str) -> type[Node]:
    """Import and return the node class registered as ``type_name``.

    Raises:
        ConfigError: unknown name (the message lists the known ones).
    """
    try:
        path = NODE_TYPES[type_name]
    except KeyError:
        raise ConfigError(f"unknown node type {type_name!r}; known: {', '.join(sorted(NODE_TYPES))}") from None
    module, _, cls = path.partition(":")
    return getattr(importlib.import_module(module), cls)
