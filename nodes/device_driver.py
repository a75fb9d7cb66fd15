"""What ft_driver and tactile_driver share: a device back-end behind a node.

A :class:`DeviceDriver` owns one back-end chosen by URL
(:func:`slipstack.nodes.devices.backends.backend_from_url`). It never blocks:

More in docs/modules.md, `nodes/device_driver.py`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, ClassVar

from slipstack.lib.errors import ConfigError
from slipstack.nodes.devices import LinkStatus
from slipstack.nodes.devices.backends import SCHEMES, Backend, Sample, backend_from_url
from slipstack.nodes.runtime.node import Context, IoSource, Node

__all__ = ["DeviceDriver"]

_STARTING = "starting"  # not a link status: the first poll reports whatever it finds
_LINK_OK = LinkStatus.OK.value  # looked up once: next_deadline_ns runs between every two simulated instants
_COUNTER_SYNC_NS = 50_000_000  # mirror back-end counters at most every 50 ms (and at stop)


@dataclass(frozen=True)
class _Fd:
    """A descriptor as an :class:`IoSource`."""

    fd: int

    def fileno(self) -> int:
        return self.fd


class DeviceDriver(Node):
    """Base of the driver nodes (module docstring). ``params`` needs ``url`` and
    ``stale_status_period_ms``."""

    kind: ClassVar[str]

    def __init__(self, params: Any = None) -> None:
        super().__init__(params)
        p = self.params
        if p.stale_status_period_ms <= 0:
            raise ConfigError(f"{self.name}: stale_status_period_ms must be > 0, got {p.stale_status_period_ms}")
        self.backend: Backend = backend_from_url(p.url)
        if self.backend.kind != self.kind:
            wanted = sorted(s for s, k in SCHEMES.items() if k == self.kind)
            raise ConfigError(f"{self.name}: {p.url!r} is a {self.backend.kind} device; use one of {wanted}")
        self.status_period_ns = round(p.stale_status_period_ms * 1e6)
        self.sample_period_s = 1.0 / self.backend.rate_hz
        self.status = _STARTING
        self._reported_error = ""
        self._last_status_pub_ns: int | None = None
        self._sources: list[IoSource] = []
        self._seen: dict[str, int] = {}
        self._next_sync_ns = 0
        self._last_stamp_ns = -1

    # -- to implement --------------------------------------------------------------------
    def on_sample(self, sample: Sample, stamp_ns: int, ctx: Context) -> None:
        """Publish one decoded sample with ``stamp_ns`` (executor clock, ns) as its stamp
        (``sample.stamp_ns`` is the time of the read that decoded it)."""
        raise NotImplementedError

    def publish_status(self, status: str, ctx: Context) -> None:
        """Publish the last good values with ``status`` (stale / disconnected)."""
        raise NotImplementedError

    def on_link_lost(self) -> None:
        """Called when the link leaves ``ok`` (e.g. restart a filter)."""

    # -- node interface --------------------------------------------------------------------
    def start(self, ctx: Context) -> None:
        self.backend.open(ctx.now_ns())  # its status is published at the first deadline, once subscribers are in

    def stop(self, ctx: Context) -> None:
        self.backend.close()
        self._sync_counters(ctx)

    def io_sources(self) -> list[IoSource]:
        fd = self.backend.fileno()
        if fd is None:
            self._sources = []
        elif not self._sources or self._sources[0].fileno() != fd:
            self._sources = [_Fd(fd)]
        return self._sources

    def on_readable(self, source: IoSource, ctx: Context) -> None:
        self._poll(ctx)

    def next_deadline_ns(self) -> int | None:
        due = self._next_sync_ns
        backend_due = self.backend.next_deadline_ns()
        if backend_due is not None and backend_due < due:
            due = backend_due
        if self.status != _LINK_OK and self._last_status_pub_ns is not None:
            due = min(due, self._last_status_pub_ns + self.status_period_ns)
        return due

    def on_deadline(self, ctx: Context) -> None:
        if self.status == _STARTING:
            self._after_poll(ctx)
        now = ctx.now_ns()
        deadline = self.backend.next_deadline_ns()
        if deadline is not None and now >= deadline:
            self._poll(ctx)
        elif self.status != _LINK_OK and now - (self._last_status_pub_ns or now) >= self.status_period_ns:
            self._publish_status(ctx)
        if now >= self._next_sync_ns:
            self._sync_counters(ctx)
            self._next_sync_ns = now + _COUNTER_SYNC_NS

    # -- internals -------------------------------------------------------------------------
    def _poll(self, ctx: Context) -> None:
        samples = self.backend.poll(ctx.now_ns())
        self._after_poll(ctx)  # link status first, so a sample's own status (size mismatch) wins
        if samples:
            for sample, stamp_ns in zip(samples, self._spread_stamps(samples)):
                self.on_sample(sample, stamp_ns, ctx)

    def _spread_stamps(self, samples: list[Sample]) -> list[int]:
        """The stamps (ns) of samples read together. They all carry the read's time; the
        earlier ones were sent earlier. Step them back by the nominal period (never before
        the previous stamp), so stamps strictly increase and say roughly when each sample
        arrived."""
        last = samples[-1].stamp_ns
        n = len(samples)
        if n == 1:
            stamps = [max(last, self._last_stamp_ns + 1)]
        else:
            period = round(1e9 / self.backend.rate_hz)
            floor = self._last_stamp_ns
            stamps = []
            for k in range(n):
                floor = max(last - (n - 1 - k) * period, floor + 1)
                stamps.append(floor)
        self._last_stamp_ns = stamps[-1]
        return stamps

    def _after_poll(self, ctx: Context) -> None:
        status = self.backend.status.value
        changed = status != self.status
        self.status = status
        if status == _LINK_OK:
            self._last_status_pub_ns = None
            if changed:
                ctx.set_status("ok")
            return
        if changed:
            self.on_link_lost()
        error = self.backend.last_error if status == LinkStatus.DISCONNECTED.value else ""
        if changed or error != self._reported_error:
            ctx.set_status(status, f"{self.params.url}: {error}" if error else self.params.url)
        if error and error != self._reported_error:
            ctx.report_error(f"{self.params.url}: {error}; retrying (back-off up to "
                             f"{self.backend.backoff_max_s:g} s). Check the device path or address (docs/drivers.md)")
        self._reported_error = error
        if changed or self._last_status_pub_ns is None or (
            ctx.now_ns() - self._last_status_pub_ns >= self.status_period_ns
        ):
            self._publish_status(ctx)

    def _publish_status(self, ctx: Context) -> None:
        self._last_status_pub_ns = ctx.now_ns()
        self.publish_status(self.status, ctx)

    def _sync_counters(self, ctx: Context) -> None:
        for key, value in self.backend.counters.items():
            delta = value - self._seen.get(key, 0)
            if delta:
                ctx.count(f"device.{key}", delta)
                self._seen[key] = value
