"""What the step kernel compiles for a contact law: its kernel family (:class:`LawKernel`).

A law's family names its scalar force kernels, the parameters they read (its *slots*, each
with the switch that needs it and its neutral value when that switch is off) and the
compile-time switches of its own. The step kernel (:mod:`engine.kernel.specialise`) reads
nothing else of a law: it packs the slot values the scene uses, generates the reader of the
family's parameter tuple and binds the family's kernels into the one contact composition
(:func:`engine.contact.compose.composition`), for the particle pairs and for the walls.

The composition's own switches (:data:`COMPOSITION_SWITCHES`) exist on both sides, and every
family's parameters include those the composition reads (:data:`COMPOSITION_PARAMS`).

Kernel contract (``@njit`` with ``NJIT_INLINE``, SI units):

``normal_force(d, dmax, r_star, law, flags) -> (f_el, stiffness, f_cap, tangent, dmax)``
    overlap d [m] (> 0), the contact's history slot dmax [m] (largest overlap, or a contact
    marker), effective radius r_star [m] (0 unless the family sets ``effective_radius``), the
    parameter tuple ``law`` and switch tuple ``flags`` of the family; returns the elastic
    (hysteretic) normal force f_el [N] (> 0 repulsive), the normal stiffness the damping sees
    [N/m], the force the Coulomb cap is taken on, f_cap [N] (``mu_s |f_cap|``), a tangent
    factor handed to ``tangential_stiffness`` and the updated history dmax [m].
``tangential_stiffness(d, r_star, law, tangent) -> kt``
    the tangential spring's stiffness [N/m] at this overlap.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

#: The contact composition's switches, on each side of a scene (pair switches unprefixed,
#: wall switches ``wall_``), with what each adds.
COMPOSITION_SWITCHES: dict[str, str] = {
    "friction": "tangential spring, friction cap and tangential history",
    "rolling": "rolling resistance",
    "damping": "viscous normal and tangential damping",
    "normal_cap": "friction cap on the total normal force mu_s |F_n| (LIGGGHTS convention)",
}

#: The parameters the composition reads from every family's tuple: damping ratio zeta,
#: sliding and rolling friction coefficients mu_s, mu_r [-].
COMPOSITION_PARAMS = ("zeta", "mu_s", "mu_r")


@dataclass(frozen=True)
class Slot:
    """One parameter of a law family as the step kernel reads it.

    Attributes: ``name`` (a field of the family's parameter tuple), ``switch`` (the switch
    that needs it; None: always read), ``neutral`` (its value when the switch is off: a
    number, or the name of another slot whose value it takes, e.g. K2 = K1 without
    plasticity).
    """

    name: str
    switch: str | None = None
    neutral: float | str = 0.0


@dataclass(frozen=True, eq=False)
class LawKernel:
    """A contact law family as the step kernel compiles it.

    Attributes:
        name: the family's name (a scene's ``pair_kernel`` / ``wall_kernel`` feature).
        module: the module that defines it (the specialised step module takes it from
            there: ``importlib.import_module(module).<attribute>``).
        attribute: its name in ``module`` (keyword only; default ``"KERNEL"``, the name
            every law module gives its family).
        params: the family's parameter tuple, a ``namedtuple`` defined at module level in
            ``module`` (a type numba's on-disk cache can name), fields in slot order.
        switch_tuple: the family's switch tuple, a module-level ``namedtuple`` whose fields are
            :data:`COMPOSITION_SWITCHES` then the family's own ``switches``.
        slots: one :class:`Slot` per field of ``params``.
        switches: the family's own compile-time switches, name -> what it adds.
        normal_force, tangential_stiffness: the scalar kernels (module docstring).
        effective_radius: the kernels read R* = Ri Rj / (Ri + Rj) (a wall: the particle's R).
    """

    name: str
    module: str
    attribute: str = field(default="KERNEL", kw_only=True)
    params: type
    switch_tuple: type
    slots: tuple[Slot, ...]
    switches: dict
    normal_force: object
    tangential_stiffness: object
    effective_radius: bool = False

    def __post_init__(self) -> None:
        names = tuple(s.name for s in self.slots)
        if tuple(self.params._fields) != names:
            raise ValueError(
                f"kernel {self.name}: params fields {self.params._fields} != slots {names}"
            )
        missing = [p for p in COMPOSITION_PARAMS if p not in names]
        if missing:
            raise ValueError(
                f"kernel {self.name}: no slot for {missing} (the composition reads them)"
            )
        fields = (*COMPOSITION_SWITCHES, *self.switches)
        if tuple(self.switch_tuple._fields) != fields:
            raise ValueError(f"kernel {self.name}: switch tuple fields must be {fields}")
        known = set(fields)
        for s in self.slots:
            if s.switch is not None and s.switch not in known:
                raise ValueError(
                    f"kernel {self.name}: slot {s.name} needs unknown switch {s.switch}"
                )
            if isinstance(s.neutral, str) and s.neutral not in names:
                raise ValueError(
                    f"kernel {self.name}: slot {s.name} has unknown neutral {s.neutral}"
                )

    @property
    def switch_names(self) -> tuple[str, ...]:
        """Every switch of this family: the composition's, then its own."""
        return tuple(self.switch_tuple._fields)

    def used_slots(self, switches: dict[str, bool]) -> tuple[str, ...]:
        """Names of the slots a kernel with ``switches`` (this side's, unprefixed) reads."""
        return tuple(s.name for s in self.slots if s.switch is None or switches[s.switch])


def pack_params(values: dict[str, float], slots: tuple[str, ...]) -> np.ndarray:
    """Flat float64 kernel parameter array: ``values[name]`` for each slot name in order, then
    a trailing NaN slot. A parameter the specialised kernel does not use has no slot (its
    reader takes the neutral value), so a slip that reads past the used ones reads the NaN
    and poisons the run instead of reading a neighbour."""
    return np.array([values[name] for name in slots] + [math.nan], dtype=np.float64)


def law_array(values: dict[str, float], kernel: LawKernel, slots=None) -> np.ndarray:
    """:func:`pack_params` of a law's slot ``values`` over ``slots`` (default: every slot of
    its ``kernel``): what a law's ``to_array`` returns."""
    return pack_params(values, tuple(s.name for s in kernel.slots) if slots is None else slots)
