"""Values as strict JSON (RFC 8259) can carry them, without the web stack: the worker stores
a failed check run's NaN values with it, and imports no FastAPI for that (about 0.2 s of
each worker process's start)."""

from __future__ import annotations

import math
from typing import Any


def finite(value: Any) -> Any:
    """``value`` as strict JSON (RFC 8259) can carry it: every non-finite float becomes the
    text JSON5 would write (``"NaN"``, ``"Infinity"``, ``"-Infinity"``), recursively. The
    422 answer echoes the input, and a body sent as ``{"name": NaN}`` must not make that
    answer itself unserialisable (Starlette's JSONResponse refuses NaN)."""
    if isinstance(value, float) and not math.isfinite(value):
        return "NaN" if math.isnan(value) else ("Infinity" if value > 0 else "-Infinity")
    if isinstance(value, dict):
        return {str(k): finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite(v) for v in value]
    return value
