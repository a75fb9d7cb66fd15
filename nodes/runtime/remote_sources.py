"""Which other machines a topic's data comes from, for a node that must say so.

In a graph over several machines, the launcher of each machine computes, for every
topic whose data passes through a node of another machine on its way (the topic graph
followed upstream, ``diagnostics`` left out: ``launch/plan.py: remote_sources``), a
label naming those machines, e.g. ``"machine robot, 127.0.0.1"``, and hands the map to
its node processes in ``$SLIPSTACK_REMOTE_SOURCES`` (JSON, topic → label). It is unset
on one machine. The grip controller names the machine when its inputs go stale, so the
operator reads on ``diagnostics`` (and in the monitor's summary) which computer went
quiet, not only in the launcher's log.
"""

from __future__ import annotations

import json
import os

from slipstack.lib.errors import ConfigError

__all__ = ["REMOTE_SOURCES_ENV", "remote_sources"]

REMOTE_SOURCES_ENV = "SLIPSTACK_REMOTE_SOURCES"
MAX_LABEL_CHARS = 200
"""Longest label kept per topic (a status line stays short)."""


def remote_sources() -> dict[str, str]:
    """Topic → the machines its data comes from, from ``$SLIPSTACK_REMOTE_SOURCES`` ({} if unset).

    Raises:
        ConfigError: the variable is set but not a JSON object of strings.
    """
    text = os.environ.get(REMOTE_SOURCES_ENV, "").strip()
    if not text:
        return {}
    try:
        doc = json.loads(text)
        if not isinstance(doc, dict) or not all(isinstance(v, str) for v in doc.values()):
            raise ValueError("not an object of strings")
    except ValueError as exc:
        raise ConfigError(f"${REMOTE_SOURCES_ENV} must be a JSON object topic → machine label ({exc}); the "
                          "launcher sets it: unset it to run a node outside a launch") from None
    return {str(topic): label[:MAX_LABEL_CHARS] for topic, label in doc.items()}
