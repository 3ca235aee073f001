"""A law file as the commands read it (``export``, ``plan``): an adhesive contact law's
JSON, ``{"type": "BilinearAdhesive" or "EEPA", fields..., "reference_radius": R}``, where
R [m] is the particle radius the law is calibrated for (``demscale calibrate`` writes it)."""

from __future__ import annotations

import math


def law_from_json(raw, owner: str | None = None, also: str = ""):
    """The law in ``raw`` (its JSON) and the particle radius it is for [m] (None where the
    file does not say). Raises ValueError naming what is wrong (a type that is not an
    adhesive law's, a reference_radius that is not a radius), or the engine's
    ParameterError naming the law's field under ``owner`` (None: the law's class); ``also``
    names what else the command takes, in the refusal of a file that is no law."""
    from engine.contact.registry import adhesive_laws
    from engine.core.records import from_dict

    laws = {c.__name__: c for c in adhesive_laws()}
    if not isinstance(raw, dict) or raw.get("type") not in laws:
        names = " or ".join(f'"{n}"' for n in laws)
        raise ValueError(f'the law must be a JSON object with "type": {names}{also}')
    body = dict(raw)
    radius = body.pop("reference_radius", None)
    if radius is not None and not (
        isinstance(radius, (int, float))
        and not isinstance(radius, bool)
        and math.isfinite(radius)
        and radius > 0
    ):
        raise ValueError(f"reference_radius = {radius!r}: must be a radius > 0 m")
    return from_dict(laws[body.pop("type")], body, owner), radius
