"""Every contact law by name (:data:`LAWS`, the ``type`` of a law in JSON), and what derives
from it: the laws a scene may take for its pairs and its walls, the laws the scaling rules act
on, the kernel families.

A law is a frozen dataclass of declared parameters (:func:`engine.core.records.param`) in its
own module, with the attributes and methods the engine asks of it:

- ``kernel``: its kernel family (:class:`engine.contact.kernel.LawKernel`: force kernels,
  slots, switches);
- ``adhesive``: whether the scaling rules act on it (K1, K2, f0, kadh: ``scaled()``,
  ``similarity_exponents()``);
- ``pair`` / ``wall``: where it may be used (a scene's pair law, its wall law);
- ``switches()``: the compile-time switches it turns on (its kernel's and the composition's);
- ``pair_values()`` / ``wall_values(wall_material)``: its slot values;
- ``pair_time_steps(...)`` / ``wall_time_steps(...)``: its time-step limits
  (:mod:`engine.contact.limits`);
- ``adhesion_overlap(rmin, fraction)``: the overlap its adhesion alone holds a contact at.
- ``load_overlap(force, radius)`` (optional): the overlap at which it carries a compressive force,
  and the parameter that sets it (a test refuses a law too soft for its consolidation stress).
- ``liggghts(owner)`` (optional): its LIGGGHTS mapping (:class:`engine.contact.export.LiggghtsPair`:
  the ``pair_style gran`` model and keywords, the ``fix property/global`` values, what LIGGGHTS
  does differently), which the exporters (engine.io.liggghts, engine.io.liggghts_deck) write as
  it is; without it the law is refused for export naming the field.

Adding a law is its module plus one line here (or ``LAWS[name] = Law`` from outside: nothing
else in the engine asks which law it has; tests/engine/test_toy_law.py does it with a law of
its own force shape).
"""

from __future__ import annotations

from .bilinear import BilinearAdhesive
from .eepa import EEPA
from .hertz import HertzMindlin

#: Every contact law by name (the ``type`` of a law in JSON).
LAWS: dict[str, type] = {
    "BilinearAdhesive": BilinearAdhesive,
    "EEPA": EEPA,
    "HertzMindlin": HertzMindlin,
}


def adhesive_laws() -> tuple[type, ...]:
    """The registered laws the scaling rules act on (``adhesive``)."""
    return tuple(c for c in LAWS.values() if c.adhesive)


def pair_laws() -> tuple[type, ...]:
    """The laws a scene may take as its pair law."""
    return tuple(c for c in LAWS.values() if c.pair)


def wall_laws() -> tuple[type, ...]:
    """The laws a scene may take as its wall law."""
    return tuple(c for c in LAWS.values() if c.wall)


def law_names(laws) -> str:
    """``engine.A, engine.B or engine.C``: the laws' names for an error message."""
    names = [f"engine.{c.__name__}" for c in laws]
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " or " + names[-1]


def kernel_named(name: str):
    """The kernel family ``name`` of a registered law (KeyError naming the known ones)."""
    for law in LAWS.values():
        if law.kernel.name == name:
            return law.kernel
    known = sorted({law.kernel.name for law in LAWS.values()})
    raise KeyError(f"no registered law has the kernel family {name!r} (known: {known})")
