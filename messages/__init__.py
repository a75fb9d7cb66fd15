"""Typed message records and their MessagePack encoding.

>>> from slipstack.messages import Wrench, encode, decode
"""

from slipstack.messages.base import Header, Message, decode, encode, registry, validate, handed_over
from slipstack.messages.types import (
    STATUS_OK, TACTILE_PAIRING, Contact, Cor, Diagnostics, GripCommand, GripState, RigTruth, Slip, TactileFrame, Wrench,
)
from slipstack.messages.grasp import GraspGoal, GraspState, GraspTruth, GripperState

__all__ = [
    "Header", "Message", "decode", "encode", "registry", "validate", "handed_over", "STATUS_OK", "TACTILE_PAIRING",
    "Contact", "Cor", "Diagnostics", "GripCommand", "GripState", "RigTruth", "Slip", "TactileFrame", "Wrench",
    "GraspGoal", "GraspState", "GraspTruth", "GripperState",
]
