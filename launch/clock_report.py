"""A launcher's clock offsets on the bus: the ``diagnostics`` of node ``launcher@MACHINE``.

In a graph over several machines every launcher publishes, once a second, a
:class:`~slipstack.messages.Diagnostics` from its own XPUB (ipc in its run directory,
and its machine's next-to-last port for the others: ``launch/plan.py:
launcher_pub_endpoints``), stamped on the graph's time base. Its counters, per other
machine ``PEER``:

More in docs/modules.md, `launch/clock_report.py`.
"""

from __future__ import annotations

import zmq

from slipstack.lib.clock_offset import OffsetEstimate
from slipstack.messages import Diagnostics, Header, encode
from slipstack.nodes.runtime.host import DIAGNOSTICS_TOPIC
from slipstack.nodes.runtime.transport import make_pub

__all__ = ["ClockReport", "launcher_node", "clock_counters", "clock_status", "REPORT_PERIOD_S"]

REPORT_PERIOD_S = 1.0
"""How often a launcher publishes its offsets (s): as often as a node its diagnostics."""


def launcher_node(machine: str) -> str:
    """The node name a launcher's diagnostics carry: ``launcher@MACHINE``."""
    return f"launcher@{machine}"


def clock_counters(estimates: dict[str, OffsetEstimate | None], time_base_offset_ns: int) -> dict[str, float]:
    """The counters of the report (module docstring); a machine not answered yet has none."""
    out: dict[str, float] = {"clock.time_base_offset_ns": float(time_base_offset_ns)}
    for peer, est in sorted(estimates.items()):
        if est is not None:
            out.update({f"clock.{peer}.offset_ns": float(est.offset_ns),
                        f"clock.{peer}.uncertainty_ns": float(est.uncertainty_ns),
                        f"clock.{peer}.exchanges": float(est.samples)})
    return out


def clock_status(estimates: dict[str, OffsetEstimate | None], warning: str = "") -> str:
    """``ok: clock of robot +0.012 ms ± 0.050 ms, ...`` or ``warning: ...`` (``warning`` given)."""
    said = ", ".join(f"clock of {peer} " + (f"{est.offset_ns / 1e6:+.3f} ms ± {est.uncertainty_ns / 1e6:.3f} ms"
                                              if est is not None else "not measured yet")
                     for peer, est in sorted(estimates.items()))
    return f"warning: {warning}; {said}" if warning else f"ok: {said}"


class ClockReport:
    """The launcher's XPUB for its ``diagnostics``; :meth:`publish` sends one report."""

    def __init__(self, zctx: zmq.Context, machine: str, endpoint: str, remote: str) -> None:
        self.node = launcher_node(machine)
        self.sock = make_pub(zctx, endpoint, sndhwm=10, remote=remote)
        self._seq = 0

    def publish(self, stamp_ns: int, estimates: dict[str, OffsetEstimate | None], time_base_offset_ns: int,
                warning: str = "") -> None:
        """One report stamped ``stamp_ns`` (the graph's time base); never blocks."""
        while self.sock.poll(0):  # subscriptions: read, so they never pile up
            self.sock.recv()
        msg = Diagnostics(node=self.node, status=clock_status(estimates, warning),
                          counters=clock_counters(estimates, time_base_offset_ns))
        try:
            self.sock.send_multipart((DIAGNOSTICS_TOPIC.encode(), encode(msg, Header(stamp_ns, self._seq, stamp_ns, {}))),
                                     zmq.NOBLOCK)
        except zmq.Again:
            pass
        self._seq += 1

    def close(self) -> None:
        self.sock.close(linger=0)
