"""A token bucket: at most ``rate_hz`` events per second on average, ``burst`` at once."""

from __future__ import annotations

__all__ = ["TokenBucket"]


class TokenBucket:
    """Admit events at ``rate_hz`` (per second of the caller's ns clock), up to ``burst`` back to back.

    The bucket starts full; each admitted event takes one token; tokens refill
    continuously at ``rate_hz`` up to ``burst``.
    """

    def __init__(self, rate_hz: float, burst: int) -> None:
        if not rate_hz > 0 or burst < 1:
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

    def take(self) -> bool:
        """Admit one event if a token is left (call :meth:`refill` first)."""
        if self.tokens >= 1.0:
            self.tokens -= 1.0
            return True
        return False
