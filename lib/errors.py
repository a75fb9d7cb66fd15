"""The one exception tree of slipstack (docs/architecture.md §10.2)."""

from __future__ import annotations

__all__ = [
    "SlipstackError",
    "DecodeError",
    "ConfigError",
    "ProtocolError",
    "DeviceError",
]


class SlipstackError(Exception):
    """Base class of every error slipstack raises on purpose."""


class DecodeError(SlipstackError):
    """A message frame could not be decoded or failed validation; names the field."""


class ConfigError(SlipstackError):
    """A parameter, launch file or scene file is invalid; says what to change."""


class ProtocolError(SlipstackError):
    """Bytes from a device do not follow its wire protocol."""


class DeviceError(SlipstackError):
    """A device cannot be reached or stopped answering."""
