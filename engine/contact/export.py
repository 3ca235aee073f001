"""What a contact law gives the LIGGGHTS exporters: its :class:`LiggghtsPair`.

A law that LIGGGHTS 3.8 can take declares its mapping next to its record, as its method
``liggghts(owner=None) -> LiggghtsPair`` (engine/contact/registry.py lists the protocol): the
``pair_style gran`` model and its keywords, the ``fix property/global`` values it sets (SI
units) with what each means, and what LIGGGHTS does differently from it. The exporters
(:mod:`engine.io.liggghts`: a fragment for one atom type; :mod:`engine.io.liggghts_deck`: a
whole uniaxial test) write what the law declares and ask nothing else of it; a law without a
mapping, or whose parameters LIGGGHTS cannot express, is refused with an
:class:`engine.ParameterError` naming the field.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class LiggghtsProperty:
    """One LIGGGHTS ``fix property/global`` value of a law.

    Attributes: ``name`` (LIGGGHTS' property name), ``value`` (SI units, or a ratio where
    ``meaning`` says so), ``meaning`` (what the value is, with its unit: a fragment's comment),
    ``scalar`` (a ``scalar`` property, else per atom type pair or per atom type), ``field``
    (the law's parameter behind it, for an error naming it) and ``unit`` (that parameter's).
    """

    name: str
    value: float
    meaning: str = ""
    scalar: bool = False
    field: str = ""
    unit: str = ""


@dataclass(frozen=True)
class LiggghtsPair:
    """A contact law as LIGGGHTS 3.8's ``pair_style gran`` (or ``wall/gran``) takes it.

    Attributes:
        law: the law's name (its ``type`` in JSON).
        model: the granular model (``edinburgh/stiffness``, ``hertz``).
        settings: the model's keywords after ``tangential history`` and the rolling
            friction's (with a leading space; "" for none).
        coefficients: the three per-atom-type-pair coefficients every granular model reads:
            ``coefficientRestitution``, ``coefficientFriction``,
            ``coefficientRollingFriction`` (:func:`gran_coefficients`).
        properties: the model's own properties, in the order they are written.
        atom_type: properties LIGGGHTS reads per atom type (Hertz: ``youngsModulus``,
            ``poissonsRatio``): one value per atom type for its pairs and walls alike, so a
            deck writes them once for the particles and the platens.
        summary: one comment line of the law's parameters (a fragment's; "" for none).
        deck_summary: the same above the model's own properties in a deck (the law's name
            first; "" for none).
        differences: what LIGGGHTS does differently from the law (a fragment's comments).
        deck_differences: what it does differently in a deck of many particles (the law's
            differences included).
        periodic_differences: what it does differently across a deck's periodic faces.
        fragment: "" when the mapping is a fragment for one atom type on its own; else why
            it is not (the law is exported in a deck only).
    """

    law: str
    model: str
    coefficients: tuple[LiggghtsProperty, ...]
    settings: str = ""
    properties: tuple[LiggghtsProperty, ...] = ()
    atom_type: tuple[LiggghtsProperty, ...] = ()
    summary: str = ""
    deck_summary: str = ""
    differences: tuple[str, ...] = ()
    deck_differences: tuple[str, ...] = ()
    periodic_differences: tuple[str, ...] = ()
    fragment: str = ""

    @property
    def rolling(self) -> bool:
        """Whether the pair style needs ``rolling_friction cdt`` (mu_r > 0)."""
        return self.coefficients[2].value > 0.0


def gran_coefficients(
    restitution: float, mu: float, mu_r: float, fields=("restitution", "mu_s", "mu_r")
) -> tuple[LiggghtsProperty, ...]:
    """The per-type-pair coefficients of every granular model: restitution [-] (it sets the
    damping), sliding friction mu [-], rolling friction mu_r [-] (``rolling_friction
    cdt``); ``fields``: the law's parameters behind them."""
    return (
        LiggghtsProperty(
            "coefficientRestitution",
            restitution,
            "normal coefficient of restitution [-] (sets the damping)",
            field=fields[0],
            unit="1",
        ),
        LiggghtsProperty(
            "coefficientFriction",
            mu,
            "sliding friction coefficient mu_s [-]",
            field=fields[1],
            unit="1",
        ),
        LiggghtsProperty(
            "coefficientRollingFriction",
            mu_r,
            "rolling friction coefficient mu_r [-] (cdt model)",
            field=fields[2],
            unit="1",
        ),
    )


def elastic_atom_type(E: float, nu: float) -> tuple[LiggghtsProperty, ...]:
    """LIGGGHTS' per-atom-type elastic properties: Young's modulus ``E`` [Pa] and Poisson's
    ratio ``nu`` [-] (a Hertz law's particles, a wall's material)."""
    return (
        LiggghtsProperty("youngsModulus", E, "Young's modulus [Pa]", field="E", unit="Pa"),
        LiggghtsProperty("poissonsRatio", nu, "Poisson's ratio [-]", field="nu", unit="1"),
    )
