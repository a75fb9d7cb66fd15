"""A token bucket: at most ``rate`` units per second on average, ``burst`` at once (frames,
bytes, or nanoseconds of work)."""

from __future__ import annotations

__all__ = ["TokenBucket"]


class TokenBucket:
    """Admit amounts at ``rate_hz`` units per second (of the caller's ns clock), up to ``burst`` back to back.

    The bucket starts full; tokens refill continuously at ``rate_hz`` up to ``burst``.
    :meth:`take` admits an amount only if that many tokens are left; :meth:`spend` charges
    work already done, and may leave the bucket in debt until it refills.
    """

    def __init__(self, rate_hz: float, burst: float) -> None:
        if not rate_hz > 0 or not burst >= 1:
            raise ValueError(f"a token bucket needs rate_hz > 0 and burst >= 1, got {rate_hz}, {burst}")
        self.rate_per_ns = rate_hz / 1e9
        self.burst = float(burst)
        self.tokens = float(burst)
        self.last_ns: int | None = None

    def refill(self, now_ns: int) -> None:
        """Add the tokens earned since the last refill (a clock going back adds none)."""
        if self.last_ns is not None and now_ns > self.last_ns:
            self.tokens = min(self.burst, self.tokens + (now_ns - self.last_ns) * self.rate_per_ns)
        if self.last_ns is None or now_ns > self.last_ns:
            self.last_ns = now_ns

    def take(self, amount: float = 1.0) -> bool:
        """Admit ``amount`` if that many tokens are left (call :meth:`refill` first)."""
        if self.tokens >= amount:
            self.tokens -= amount
            return True
        return False

    def spend(self, amount: float) -> None:
        """Charge ``amount`` already used, into debt if need be."""
        self.tokens -= amount

    def ns_until(self, level: float) -> int:
        """How long (ns) until the bucket holds ``level`` tokens (0 if it does)."""
        return 0 if self.tokens >= level else int((level - self.tokens) / self.rate_per_ns) + 1
