"""A per-token rate limit on submissions (``POST /studies`` and ``POST /calibrations``, one
bucket for both), refused ones included: each
costs the server the admission's work, a refused one as much as an accepted one.

A token bucket per token fingerprint: ``submit_burst`` submissions at once, refilled at
``submit_rate`` a minute. An empty bucket answers 429 with ``Retry-After`` (seconds until the
next submission is allowed) before the body is read. The buckets live in the API process
(one per server; they restart empty-handed, i.e. full, with it).
"""

from __future__ import annotations

import math
import threading
import time

from .guard import _answer

#: The submissions the limit counts.
SUBMIT_PATHS = frozenset({"/studies", "/calibrations"})
#: Buckets kept at most (least recently used dropped): bounded memory whatever the tokens.
MAX_BUCKETS = 10_000


class Buckets:
    """Token buckets keyed by owner: ``take(owner)`` returns 0 when allowed, else the
    seconds to wait."""

    def __init__(self, per_minute: float, burst: int, clock=time.monotonic):
        self.rate = per_minute / 60.0
        self.burst = float(burst)
        self.clock = clock
        self._state: dict[str, tuple[float, float]] = {}
        self._lock = threading.Lock()

    def take(self, owner: str) -> float:
        now = self.clock()
        with self._lock:
            level, then = self._state.pop(owner, (self.burst, now))
            level = min(self.burst, level + (now - then) * self.rate)
            if level >= 1.0:
                self._state[owner] = (level - 1.0, now)
                wait = 0.0
            else:
                self._state[owner] = (level, now)
                wait = (1.0 - level) / self.rate
            while len(self._state) > MAX_BUCKETS:
                self._state.pop(next(iter(self._state)))
        return wait


class SubmitRateLimit:
    """ASGI middleware inside :class:`service.guard.Guard` (the owner is known): 429 with
    ``Retry-After`` for a submission (:data:`SUBMIT_PATHS`) beyond the token's rate."""

    def __init__(self, app, per_minute: float, burst: int):
        self.app = app
        self.buckets = Buckets(per_minute, burst)

    async def __call__(self, scope, receive, send) -> None:
        if (
            scope["type"] == "http"
            and scope["method"] == "POST"
            and scope["path"].rstrip("/") in SUBMIT_PATHS
        ):
            owner = scope.get("state", {}).get("owner")
            if owner is not None:
                wait = self.buckets.take(owner)
                if wait > 0:
                    retry = max(1, math.ceil(wait))
                    await _answer(
                        send,
                        429,
                        "too many submissions from this token: try again "
                        f"in {retry} s (DEMSCALE_SUBMIT_RATE per minute, bursts of "
                        "DEMSCALE_SUBMIT_BURST)",
                        {"Retry-After": str(retry)},
                    )
                    return
        await self.app(scope, receive, send)
