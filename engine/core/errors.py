"""Exceptions of the engine. Every message names the field or quantity and the limit.

Every exception pickles with its attributes (``__reduce__``): a run on a process pool or a
Dask worker sends its error back to the study, which stores it as the run's outcome. (A
pickled exception is rebuilt from ``args`` alone by default, which fails for constructors
with more arguments than the message and broke the whole pool.)
"""

from __future__ import annotations


class ParameterError(ValueError):
    """A parameter is outside its allowed range.

    Attributes: ``field`` (dotted name, e.g. ``"BilinearAdhesive.k2"``) and ``limit`` (text of
    the allowed range).
    """

    def __init__(self, field: str, value: object, limit: str, why: str = "") -> None:
        self.field = field
        self.value = value
        self.limit = limit
        self.why = why
        msg = f"{field} = {value!r} is not allowed: must be {limit}"
        if why:
            msg += f" ({why})"
        super().__init__(msg)

    def __reduce__(self):
        return type(self), (self.field, self.value, self.limit, self.why)


class MissingField(ParameterError):
    """A request leaves out what it must give (engine.core.inputs): ``field`` names where,
    ``limit`` what is needed ("given": the field itself), ``why`` the reason. Its message
    reads ``field: required (why)``, or ``field: limit (why)``."""

    def __init__(self, field: str, value: object = None, limit: str = "given", why: str = ""):
        super().__init__(field, value, limit, why)
        text = f"{field}: required" if limit == "given" else f"{field}: {limit}"
        self.args = (f"{text} ({why})" if why else text,)


class StabilityError(ValueError):
    """A requested time step (or parameter set) cannot be integrated stably.

    Attributes: ``dt`` (the requested step [s], or None) and ``limit`` (the stable limit [s]).
    """

    def __init__(self, message: str, dt: float | None = None, limit: float | None = None):
        self.dt = dt
        self.limit = limit
        super().__init__(message)

    def __reduce__(self):
        return type(self), (self.args[0], self.dt, self.limit)


class InstabilityError(RuntimeError):
    """A run blew up: NaN/inf, an overlap beyond the allowed fraction of the radius, or a
    particle moving further than the allowed fraction of its radius in one step.

    Attributes: ``step`` (steps since the simulation started), ``time`` [s], ``particles``
    (tuple of offending particle ids), ``reason`` (``"nan"``, ``"overlap"``, ``"speed"``).
    """

    def __init__(self, message: str, *, step: int, time: float, particles: tuple, reason: str):
        self.step = step
        self.time = time
        self.particles = particles
        self.reason = reason
        super().__init__(message)

    def __reduce__(self):
        return _instability_error, (
            type(self),
            self.args[0],
            self.step,
            self.time,
            self.particles,
            self.reason,
        )


def _instability_error(cls, message, step, time, particles, reason):
    """Unpickle an :class:`InstabilityError` (its fields are keyword-only)."""
    return cls(message, step=step, time=time, particles=particles, reason=reason)


class StopRequested(RuntimeError):
    """Raised out of a stage driver or study when the progress callback asked to stop."""


class WallTimeExceeded(RuntimeError):
    """A run went on past its limit on wall time (``run_uniaxial(max_wall_time=...)``).

    Attributes: ``limit`` and ``elapsed`` [s] of wall time (set-up, i.e. kernel compilation,
    left out; a run resumed from a checkpoint counts the time of its earlier attempts up to
    that checkpoint), ``setting`` (the name of the knob that set the limit).
    """

    def __init__(self, limit: float, elapsed: float, setting: str = "max_wall_time"):
        self.limit = limit
        self.elapsed = elapsed
        self.setting = setting
        super().__init__(
            f"the run went on for {elapsed:.4g} s of wall time, more than "
            f"{setting} = {limit:g} s: it was stopped; use a smaller or shorter "
            "test, or raise the limit"
        )

    def __reduce__(self):
        return type(self), (self.limit, self.elapsed, self.setting)
