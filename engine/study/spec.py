"""What a scaling study runs: :class:`ScalingRule`, :class:`StudySpec` and the planned runs
(docs/PHYSICS.md section 5).

Every field is declared with its unit and bounds (:mod:`engine.core.records`); the job service
builds its request schema from these declarations, and the named rules exist once, here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from ..contact.bilinear import BilinearAdhesive
from ..core.errors import ParameterError
from ..core.records import check_fields, param
from ..uniaxial.spec import UniaxialTest, preset
from .metrics import DEFAULT_TOLERANCES, METRICS

DT_POLICIES = ("fixed", "scaled")

#: The named rules: name -> (stiffness exponent a, adhesion exponent b, what it stands for).
#: a = None: geometric and stress similarity for the reference law, K ~ R^(2-n) and
#: kadh ~ R^(2-chi) (docs/PHYSICS.md section 8); for the bilinear law (n = chi = 1) that is
#: the paper's rule.
NAMED_RULES = {
    "paper": (1.0, 2.0, "Thakur et al. 2013: stiffness ~ R, adhesion ~ R^2"),
    "unscaled": (0.0, 0.0, "parameters of the reference, unchanged"),
    "linear_adhesion": (1.0, 1.0, "stiffness ~ R, adhesion ~ R"),
    "cubic_adhesion": (1.0, 3.0, "stiffness ~ R, adhesion ~ R^3"),
    "similarity": (None, 2.0, "stress similarity: K1, K2 ~ R^(2-n), kadh ~ R^(2-chi), f0 ~ R^2"),
}


@dataclass(frozen=True)
class ScalingRule:
    """How the pair-law parameters follow the radius, with s = R / R_ref.

    Attributes:
        name: label of the rule (used in run keys and plots).
        stiffness_exponent: a in K1, K2, Kt ~ s^a [-]; None: the reference law's stress
            similarity, a = 2 - n (1 for the bilinear law).
        adhesion_exponent: b in f0 ~ s^b [-].
        dt: ``"fixed"`` (the reference's time step) or ``"scaled"`` (reference dt times s).
        adhesive_exponent: c in kadh ~ s^c [-]; None: as the stiffness (the number a, or
            with ``stiffness_exponent=None`` the similarity value 2 - chi).
    """

    name: str = param(unit="", kind="str", doc="label: 1-40 of letters, digits, '_', '-', '.'")
    stiffness_exponent: float | None = param(
        1.0,
        unit="1",
        ge=-1,
        le=4,
        nullable=True,
        doc="a in K1, K2, Kt ~ (R/R_ref)^a; null: stress similarity, a = 2 - n",
    )
    adhesion_exponent: float = param(2.0, unit="1", ge=-1, le=5, doc="b in f0 ~ (R/R_ref)^b")
    dt: str = param(
        "fixed",
        unit="",
        kind="str",
        choices=DT_POLICIES,
        doc="time step of coarse runs: the reference's, or scaled by R/R_ref",
    )
    adhesive_exponent: float | None = param(
        None,
        unit="1",
        ge=-1,
        le=5,
        nullable=True,
        doc="c in kadh ~ (R/R_ref)^c; null: as the stiffness (similarity: 2 - chi)",
    )

    def __post_init__(self) -> None:
        o = "ScalingRule"
        if (
            not isinstance(self.name, str)
            or not self.name
            or len(self.name) > 40
            or not all(c.isalnum() or c in "_-." for c in self.name)
        ):
            raise ParameterError(
                f"{o}.name", self.name, "1 to 40 characters among letters, digits, '_', '-', '.'"
            )
        check_fields(self, o)

    @classmethod
    def named(cls, name: str, dt: str = "fixed") -> ScalingRule:
        """A rule of :data:`NAMED_RULES`: ``paper`` (a = 1, b = 2), ``unscaled`` (a = b = 0),
        ``linear_adhesion`` (a = 1, b = 1), ``cubic_adhesion`` (a = 1, b = 3),
        ``similarity`` (a = 2 - n, b = 2, c = 2 - chi of the reference law)."""
        if name not in NAMED_RULES:
            raise ParameterError("ScalingRule.name", name, f"one of {sorted(NAMED_RULES)}")
        a, b, _ = NAMED_RULES[name]
        return cls(name, a, b, dt)

    def apply(self, reference: UniaxialTest, radius: float, reference_dt: float) -> UniaxialTest:
        """The test of ``reference`` with particles of ``radius`` [m] and the pair law scaled
        by this rule. The platen (Hertz) law is unchanged: it is already stress-similar."""
        s = radius / reference.radius
        law = reference.pair_law.scaled(s, *self.exponents(reference.pair_law))
        dt = reference_dt * (s if self.dt == "scaled" else 1.0)
        return replace(reference, radius=radius, pair_law=law, dt=dt)

    def exponents(self, law) -> tuple[float, float, float]:
        """The exponents (a, b, c) of K1/K2/Kt, f0 and kadh this rule gives ``law``."""
        if self.stiffness_exponent is None:
            a, _, c = law.similarity_exponents()
        else:
            a = c = self.stiffness_exponent
        if self.adhesive_exponent is not None:
            c = self.adhesive_exponent
        return a, self.adhesion_exponent, c

    def to_dict(self) -> dict:
        return {
            "name": self.name,
            "stiffness_exponent": self.stiffness_exponent,
            "adhesion_exponent": self.adhesion_exponent,
            "dt": self.dt,
            "adhesive_exponent": self.adhesive_exponent,
        }


def _seed_list(owner: str, seeds) -> tuple[int, ...]:
    seeds = tuple(seeds)
    if (
        not 1 <= len(seeds) <= 10
        or len(set(seeds)) != len(seeds)
        or not all(isinstance(s, int) and not isinstance(s, bool) and 0 <= s < 2**31 for s in seeds)
    ):
        raise ParameterError(owner, seeds, "1 to 10 distinct integers in [0, 2^31)")
    return seeds


@dataclass(frozen=True)
class StudySpec:
    """A scaling study.

    Attributes:
        reference: the fine reference test (its radius is R_ref and its pair law the
            reference parameters; a :class:`engine.BilinearAdhesive` or :class:`engine.EEPA`
            law).
        coarse_radii: radii of the coarse variants [m], each != the reference radius.
        rules: scaling rules applied to every coarse radius (names unique).
        seeds: packing seeds of every coarse variant (default: the reference seeds).
        reference_seeds: packing seeds of the reference runs (default: ``seeds``, or the
            reference's own seed). Two or more give the noise floor the verdicts need.
        tolerances: per verdict metric, the largest accepted relative error [-]; metrics
            left out keep :data:`engine.study.metrics.DEFAULT_TOLERANCES`.
        interior_diameters: the layer next to each platen left out of the interior porosity
            and coordination of every run, in diameters of the study's largest particle [-].
        confidence: of every verdict: a wrong ``equivalent`` or a wrong ``differs`` is said
            in at most 1 - confidence of studies [-] (engine.study.advisor).
        decide: after the planned runs, add seeds where a verdict is undecided, in up to
            ``rounds`` rounds, until every verdict is decided, a cap or the budget is hit.
        max_seeds: with ``decide``, most seeds of one coarse variant (planned ones included).
        max_reference_seeds: with ``decide``, most reference seeds (planned ones included).
        rounds: with ``decide``, most rounds of added runs; the verdicts spend their error
            rate over rounds + 1 looks, so adding seeds keeps the stated confidence.
        budget: with ``decide``, most particle-steps of the added runs (estimated before each
            is started); None: the caps alone bound them.
    """

    reference: UniaxialTest = param(
        unit="",
        kind="record",
        default_factory=lambda: preset("quick"),
        doc="the fine reference test",
    )
    coarse_radii: tuple[float, ...] = param(
        (5e-3,), unit="m", kind="list", max_items=8, doc="radii of the coarse variants"
    )
    rules: tuple[ScalingRule, ...] = param(
        unit="",
        kind="list",
        max_items=8,
        default_factory=lambda: (ScalingRule.named("paper"), ScalingRule.named("unscaled")),
        doc="scaling rules applied to every coarse radius (or names of NAMED_RULES)",
    )
    seeds: tuple[int, ...] | None = param(
        None, unit="", kind="list", nullable=True, max_items=10, doc="packing seeds of coarse runs"
    )
    reference_seeds: tuple[int, ...] | None = param(
        None,
        unit="",
        kind="list",
        nullable=True,
        max_items=10,
        doc="packing seeds of the reference runs (>= 2 for a noise floor)",
    )
    tolerances: dict | None = param(
        None,
        unit="1",
        kind="dict",
        nullable=True,
        doc="largest accepted relative error per verdict metric",
    )
    interior_diameters: float = param(
        2.0,
        unit="1",
        ge=2,
        le=10,
        doc="platen layer left out of interior measurements, in largest diameters",
    )
    confidence: float = param(
        0.95,
        unit="1",
        gt=0.5,
        lt=1.0,
        doc="confidence of every verdict (1 - its largest error rate)",
    )
    decide: bool = param(
        False,
        unit="",
        kind="bool",
        doc="add seeds where a verdict is undecided, until decided or capped",
    )
    max_seeds: int = param(
        10, unit="1", kind="int", ge=2, le=30, doc="with decide: most seeds of one coarse variant"
    )
    max_reference_seeds: int = param(
        5, unit="1", kind="int", ge=2, le=30, doc="with decide: most reference seeds"
    )
    rounds: int = param(
        3, unit="1", kind="int", ge=1, le=10, doc="with decide: most rounds of added runs"
    )
    budget: float | None = param(
        None,
        unit="1",
        gt=0,
        nullable=True,
        doc="with decide: most particle-steps of the added runs",
    )

    def __post_init__(self) -> None:
        o = "StudySpec"
        if not isinstance(self.reference, UniaxialTest):
            raise ParameterError(f"{o}.reference", self.reference, "an engine.UniaxialTest")
        if not getattr(self.reference.pair_law, "adhesive", False):
            raise ParameterError(
                f"{o}.reference.pair_law",
                type(self.reference.pair_law).__name__,
                "a BilinearAdhesive or EEPA law (the scaling rules act on K1, K2, f0, kadh)",
            )
        check_fields(self, o)
        radii = tuple(self.coarse_radii)
        if not 1 <= len(radii) <= 8:
            raise ParameterError(f"{o}.coarse_radii", radii, "1 to 8 radii")
        r_ref = self.reference.radius
        for i, r in enumerate(radii):
            f = f"{o}.coarse_radii[{i}]"
            if isinstance(r, bool) or not isinstance(r, (int, float)) or not math.isfinite(r):
                raise ParameterError(f, r, "a finite number of metres")
            if not 0 < r <= 4 * r_ref or abs(r - r_ref) <= 1e-9 * r_ref:
                raise ParameterError(
                    f,
                    r,
                    f"in (0, {4 * r_ref:g}] m (4 reference radii) and "
                    f"different from the reference radius {r_ref:g} m",
                )
        if len(set(radii)) != len(radii):
            raise ParameterError(f"{o}.coarse_radii", radii, "distinct radii")
        object.__setattr__(self, "coarse_radii", tuple(float(r) for r in radii))
        rules = tuple(self.rules)
        if not 1 <= len(rules) <= 8 or not all(isinstance(r, ScalingRule) for r in rules):
            raise ParameterError(f"{o}.rules", rules, "1 to 8 engine.ScalingRule")
        if len({r.name for r in rules}) != len(rules):
            raise ParameterError(f"{o}.rules", [r.name for r in rules], "rules with unique names")
        object.__setattr__(self, "rules", rules)
        seeds = None if self.seeds is None else _seed_list(f"{o}.seeds", self.seeds)
        ref_seeds = (
            _seed_list(f"{o}.reference_seeds", self.reference_seeds)
            if (self.reference_seeds is not None)
            else (seeds or (self.reference.seed,))
        )
        seeds = seeds or ref_seeds
        object.__setattr__(self, "reference_seeds", ref_seeds)
        object.__setattr__(self, "seeds", seeds)
        tol = dict(DEFAULT_TOLERANCES)
        for k, v in (self.tolerances or {}).items():
            if k not in METRICS:
                raise ParameterError(f"{o}.tolerances", k, f"a metric among {sorted(METRICS)}")
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 < v <= 1:
                raise ParameterError(f"{o}.tolerances.{k}", v, "in (0, 1]")
            tol[k] = float(v)
        object.__setattr__(self, "tolerances", tol)
        if self.decide and self.max_seeds < len(seeds):
            raise ParameterError(
                f"{o}.max_seeds", self.max_seeds, f">= the {len(seeds)} planned seeds"
            )
        if self.decide and self.max_reference_seeds < len(ref_seeds):
            raise ParameterError(
                f"{o}.max_reference_seeds",
                self.max_reference_seeds,
                f">= the {len(ref_seeds)} planned reference seeds",
            )
        # one interior window for every run: a layer of interior_diameters largest diameters
        margin = (
            self.interior_diameters * 2 * max((*radii, r_ref)) * (1 + self.reference.polydispersity)
        )
        ref = replace(self.reference, interior_margin=margin)
        object.__setattr__(self, "reference", ref)
        # every coarse test must itself be runnable: the cell holds the coarse radius, the
        # scaled adhesion and the (fixed or scaled) time step are within the engine's limits
        dt_ref = self.reference.resolved_dt()
        for i, r in enumerate(self.coarse_radii):
            for rule in self.rules:
                try:
                    rule.apply(self.reference, r, dt_ref)
                except ParameterError as e:
                    raise ParameterError(
                        f"{o}.coarse_radii[{i}]",
                        r,
                        "a radius the reference's cell and laws can run",
                        f"with rule {rule.name!r}: {e}",
                    ) from None

    def planned_runs(self) -> list:
        """Every run: the references first (one per reference seed), then every coarse
        variant for every seed. Each test is complete: a coarse run with ``dt="fixed"``
        takes the reference's time step, which is known before the reference runs.

        Planned once per spec (the record is frozen, so is its plan): admission, the cost
        estimate, the worker and the study all read the same list."""
        from .plan import PlannedRun, run_key

        cached = self.__dict__.get("_plan")
        if cached is not None:
            return list(cached)
        out = []
        dt_ref = self.reference.resolved_dt()
        for seed in self.reference_seeds:
            ref = replace(self.reference, seed=seed)
            out.append(PlannedRun(run_key(ref.radius, None, seed), ref.radius, None, seed, ref))
        for seed in self.seeds:
            ref = replace(self.reference, seed=seed)
            for r in self.coarse_radii:
                for rule in self.rules:
                    test = rule.apply(ref, r, dt_ref)
                    out.append(PlannedRun(run_key(r, rule, seed), r, rule, seed, test))
        object.__setattr__(self, "_plan", tuple(out))
        return list(out)

    @property
    def looks(self) -> int:
        """How many times the verdicts may be judged: 1, or rounds + 1 with ``decide``."""
        return self.rounds + 1 if self.decide else 1

    def max_particles(self) -> int:
        """The largest particle count of any run."""
        return max(p.test.n_particles for p in self.planned_runs())

    def estimated_particle_steps(self) -> float:
        """Estimate of the study's total particle-steps (for admission limits): the planned
        runs, and with ``decide`` the most its added runs may cost (the ``budget``, or every
        variant and the reference filled to their seed caps, whichever is less)."""
        from .plan import estimated_steps

        planned = self.planned_runs()
        cost = {}
        for p in planned:
            cost.setdefault(
                (p.radius, None if p.rule is None else p.rule.name),
                estimated_steps(p.test) * p.test.n_particles,
            )
        total = float(sum(estimated_steps(p.test) * p.test.n_particles for p in planned))
        if not self.decide:
            return total
        worst = sum(
            c * (self.max_reference_seeds - len(self.reference_seeds))
            if k[1] is None
            else c * (self.max_seeds - len(self.seeds))
            for k, c in cost.items()
        )
        return total + float(worst if self.budget is None else min(worst, self.budget))

    def to_dict(self) -> dict:
        """JSON-friendly form (inverse: :meth:`from_dict`)."""
        ref = self.reference.to_dict()
        ref["interior_margin"] = None  # derived from interior_diameters again on load
        return {
            "reference": ref,
            "coarse_radii": list(self.coarse_radii),
            "rules": [r.to_dict() for r in self.rules],
            "seeds": list(self.seeds),
            "reference_seeds": list(self.reference_seeds),
            "tolerances": dict(self.tolerances),
            "interior_diameters": self.interior_diameters,
            "confidence": self.confidence,
            "decide": self.decide,
            "max_seeds": self.max_seeds,
            "max_reference_seeds": self.max_reference_seeds,
            "rounds": self.rounds,
            "budget": self.budget,
        }

    @classmethod
    def from_dict(cls, d: dict) -> StudySpec:
        """Build from :meth:`to_dict` output. ``reference`` may hold ``"preset": "quick"``
        (or ``"paper"``) with overrides; rules may be given by name only."""
        d = dict(d)
        known = {
            "reference",
            "coarse_radii",
            "rules",
            "seeds",
            "reference_seeds",
            "tolerances",
            "interior_diameters",
            "confidence",
            "decide",
            "max_seeds",
            "max_reference_seeds",
            "rounds",
            "budget",
        }
        if set(d) - known:
            raise ParameterError(
                "StudySpec", sorted(set(d) - known), f"fields among {sorted(known)}"
            )
        ref = d.get("reference", {"preset": "quick"})
        if isinstance(ref, dict):
            ref = dict(ref)
            name = ref.pop("preset", None)
            if name is not None:
                base = preset(name).to_dict()
                base.update(ref)
                ref = base
            d["reference"] = UniaxialTest.from_dict(ref)
        for k in ("seeds", "reference_seeds", "tolerances"):
            if k in d and d[k] is None:
                del d[k]
        for k in ("coarse_radii", "rules", "seeds", "reference_seeds"):
            if k in d and not isinstance(d[k], (list, tuple)):
                raise ParameterError(f"StudySpec.{k}", d[k], "a list")
        if "tolerances" in d and not isinstance(d["tolerances"], dict):
            raise ParameterError(
                "StudySpec.tolerances", d["tolerances"], "an object of metric name -> tolerance"
            )
        if "rules" in d:
            rules = []
            for i, r in enumerate(d["rules"]):
                if isinstance(r, str):
                    rules.append(ScalingRule.named(r))
                elif isinstance(r, dict):
                    try:
                        rules.append(ScalingRule(**r))
                    except TypeError as e:
                        raise ParameterError(
                            f"StudySpec.rules[{i}]",
                            r,
                            "fields name, "
                            "stiffness_exponent, adhesion_exponent, dt, "
                            "adhesive_exponent",
                        ) from e
                else:
                    rules.append(r)
            d["rules"] = tuple(rules)
        for k in ("coarse_radii", "seeds", "reference_seeds"):
            if k in d:
                d[k] = tuple(d[k])
        return cls(**d)


def default_study() -> StudySpec:
    """The study the main job runs: the ``quick`` cohesive reference (R = 2.5 mm,
    f0 = -0.4 N) against R = 3.75 and 5 mm with the paper's rule and with unscaled
    parameters, two seeds each: two reference seeds give the noise floor, and two seeds per
    variant measure the variant's own spread (a coarse bed of fewer particles scatters more
    than the reference, so one seed would understate it). Where a verdict stays undecided it
    adds seeds in one round (up to four per variant and three reference seeds, within 1.5e9
    particle-steps: half the planned runs' cost)."""
    ref = preset(
        "quick",
        pair_law=BilinearAdhesive(k1=5e3, k2=2.5e4, f0=-0.4, mu_s=0.5, mu_r=0.001, restitution=0.4),
    )
    return StudySpec(
        reference=ref,
        coarse_radii=(3.75e-3, 5e-3),
        rules=(ScalingRule.named("paper"), ScalingRule.named("unscaled")),
        seeds=(1, 2),
        reference_seeds=(1, 2),
        decide=True,
        rounds=1,
        max_seeds=4,
        max_reference_seeds=3,
        budget=1.5e9,
    )
