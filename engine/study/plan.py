"""The runs of a scaling study.

:func:`plan` turns a :class:`~engine.study.spec.StudySpec` into its :class:`StudyPlan` once:
the references (one per reference seed), then every coarse radius x rule per seed, each test
complete (its time step known before any run starts) and checked runnable; nothing is placed
or run. A plan has a JSON form (:meth:`StudyPlan.to_dict`): the job service stores it with the
job and its worker runs the stored plan. The plan is static: with ``decide``, the runs each
round adds are the adaptive loop's (engine.study.loop), as planned runs of this plan with new
seeds (:meth:`PlannedRun.with_seed`, :func:`stored_plan_runs`)."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..core.errors import ParameterError
from ..shear.spec import ShearTest
from ..uniaxial.spec import UniaxialTest
from .kinds import kind_of
from .spec import ScalingRule, StudySpec

#: The variant name of a study's resolution controls (a rule may not take it).
CONTROL = "control"
#: The variant name of a study's protocol check: reference seeds at half the rate and step.
PROTOCOL = "protocol"


@dataclass(frozen=True)
class PlannedRun:
    """One run of a study: ``key``, ``radius`` [m] (a control's: the coarse radius it stands
    for), ``rule`` (None for a reference or a control), ``seed``, its ``test`` (complete: a
    coarse run's time step is known before any run starts) and whether it is a resolution
    ``control`` (:func:`control_test`) or a ``protocol`` check (a reference seed at half the
    rate and step, :func:`engine.uniaxial.spec.halved_protocol`)."""

    key: str
    radius: float
    rule: ScalingRule | None
    seed: int
    test: UniaxialTest | ShearTest
    control: bool = False
    protocol: bool = False

    @property
    def is_reference(self) -> bool:
        return self.rule is None and not self.control and not self.protocol

    @property
    def variant(self) -> tuple[float, str] | None:
        """(radius [m], rule name, :data:`CONTROL` or :data:`PROTOCOL`) of a coarse run, a
        control or a protocol check; None for a reference."""
        if self.control:
            return (self.radius, CONTROL)
        if self.protocol:
            return (self.radius, PROTOCOL)
        return None if self.rule is None else (self.radius, self.rule.name)

    @property
    def label(self) -> str:
        """``"reference"``, ``"control"``, ``"protocol"`` or the rule's name."""
        if self.control:
            return CONTROL
        if self.protocol:
            return PROTOCOL
        return "reference" if self.rule is None else self.rule.name

    def with_seed(self, seed: int) -> PlannedRun:
        """The same run with packing seed ``seed`` (its key says so)."""
        return PlannedRun(
            run_key(self.radius, self.rule, seed, self.control, self.protocol),
            self.radius,
            self.rule,
            seed,
            replace(self.test, seed=seed),
            self.control,
            self.protocol,
        )

    @property
    def particle_steps(self) -> float:
        """Estimated particle-steps of the run (:func:`estimated_steps` x particles)."""
        return estimated_steps(self.test) * self.test.n_particles


def run_key(
    radius: float,
    rule: ScalingRule | None,
    seed: int,
    control: bool = False,
    protocol: bool = False,
) -> str:
    """Key of a run, e.g. ``ref-s1``, ``r5mm-paper-s1``, (a control) ``ctl-r5mm-s1`` or (a
    protocol check) ``half-s1``."""
    if control:
        return f"ctl-r{radius * 1e3:g}mm-s{seed}"
    if protocol:
        return f"half-s{seed}"
    if rule is None:
        return f"ref-s{seed}"
    return f"r{radius * 1e3:g}mm-{rule.name}-s{seed}"


def estimated_steps(test: UniaxialTest | ShearTest) -> float:
    """Rough step count of a test, as its kind estimates it (:mod:`engine.study.kinds`:
    ``uniaxial_steps``, ``shear_steps``)."""
    return kind_of(test).estimated_steps(test)


def reference_test(spec: StudySpec) -> UniaxialTest | ShearTest:
    """The study's reference test: the spec's reference with the study's interior window, a
    layer of ``interior_diameters`` diameters of the study's largest particle at each platen,
    the same for every run (a shear reference as it is: its bulk density's window is in
    each run's own diameters)."""
    ref = spec.reference
    if not kind_of(ref).window:
        return ref
    margin = spec.interior_diameters * 2 * max((*spec.coarse_radii, ref.radius))
    return replace(ref, interior_margin=margin * (1 + ref.polydispersity))


def control_test(reference, radius: float, reference_dt: float):
    """The resolution control of coarse radius ``radius`` [m]: the ``reference`` law unscaled
    in the reference test scaled by s = R_ref / radius, as the reference's kind makes it
    (docs/PHYSICS.md section 7.4; :func:`engine.study.kinds.uniaxial_control_test`,
    :func:`engine.shear.spec.control_test`)."""
    return kind_of(reference).control_test(reference, radius, reference_dt)


@dataclass(frozen=True)
class StudyPlan:
    """The planned runs of a study (:func:`plan`): ``spec`` and ``runs`` (references first)."""

    spec: StudySpec
    runs: tuple[PlannedRun, ...]

    def max_particles(self) -> int:
        """The largest particle count of any run."""
        return max(p.test.n_particles for p in self.runs)

    def estimated_particle_steps(self) -> float:
        """Estimate of the study's total particle-steps (for admission limits): the planned
        runs, and with ``decide`` the most its added runs may cost (the ``budget``, or every
        variant and the reference filled to their seed caps, whichever is less)."""
        spec = self.spec
        total = float(sum(p.particle_steps for p in self.runs))
        if not spec.decide:
            return total
        worst = to_seed_caps(spec, self.runs)
        return total + float(worst if spec.budget is None else min(worst, spec.budget))

    def to_dict(self) -> dict:
        """JSON form: the spec and every run with its complete test (inverse
        :meth:`from_dict`)."""
        return {
            "spec": self.spec.to_dict(),
            "runs": [
                {
                    "key": p.key,
                    "radius": p.radius,
                    "rule": None if p.rule is None else p.rule.name,
                    "seed": p.seed,
                    "test": p.test.to_dict(),
                    **({"control": True} if p.control else {}),
                    **({"protocol": True} if p.protocol else {}),
                }
                for p in self.runs
            ],
        }

    @classmethod
    def from_dict(cls, d: dict) -> StudyPlan:
        """The plan of :meth:`to_dict`, read back without planning again (the records are
        validated, nothing is placed)."""
        spec = StudySpec.from_dict(d["spec"])
        rules = {r.name: r for r in spec.rules}
        runs = tuple(
            PlannedRun(
                r["key"],
                float(r["radius"]),
                None if r["rule"] is None else rules[r["rule"]],
                int(r["seed"]),
                type(spec.reference).from_dict(r["test"]),
                bool(r.get("control", False)),
                bool(r.get("protocol", False)),
            )
            for r in d["runs"]
        )
        return cls(spec, runs)


def to_seed_caps(spec: StudySpec, runs) -> float:
    """Particle-steps of the runs that would fill the reference and every variant of
    ``runs`` up to their seed caps (``max_reference_seeds``, ``max_seeds``; a control
    follows the added coarse seeds of its radius; the protocol check adds none)."""
    cost: dict = {}
    count: dict = {}
    for p in runs:
        cost.setdefault(p.variant, p.particle_steps)
        count[p.variant] = count.get(p.variant, 0) + 1
    return float(
        sum(
            c * max(0, (spec.max_reference_seeds if k is None else spec.max_seeds) - count[k])
            for k, c in cost.items()
            if k is None or k[1] != PROTOCOL
        )
    )


def plan(spec: StudySpec) -> StudyPlan:
    """Every run of ``spec``: the references first (one per reference seed), then for every
    seed every coarse variant and, with ``controls``, each radius's resolution control
    (:func:`control_test`). Each test is complete: a coarse run with ``dt="fixed"``
    takes the reference's time step, which is known before the reference runs; each must be
    runnable (the cell holds the coarse radius, the scaled adhesion and the time step are
    within the engine's limits), else :class:`engine.ParameterError` names the coarse radius.
    Pure: nothing is placed or run, and the spec is not changed."""
    ref = reference_test(spec)
    dt_ref = ref.resolved_dt()
    coarse = {}
    for i, r in enumerate(spec.coarse_radii):
        for rule in spec.rules:
            try:
                coarse[r, rule.name] = rule.apply(ref, r, dt_ref)
            except ParameterError as e:
                raise ParameterError(
                    f"StudySpec.coarse_radii[{i}]",
                    r,
                    "a radius the reference's cell and laws can run",
                    f"with rule {rule.name!r}: {e}",
                ) from None
    controls = {}
    if spec.controls:
        for i, r in enumerate(spec.coarse_radii):
            try:
                controls[r] = control_test(ref, r, dt_ref)
            except ParameterError as e:
                raise ParameterError(
                    f"StudySpec.coarse_radii[{i}]",
                    r,
                    "a radius whose resolution control the reference's cell can hold",
                    f"(or controls=False): {e}",
                ) from None
    out = [
        PlannedRun(run_key(ref.radius, None, seed), ref.radius, None, seed, replace(ref, seed=seed))
        for seed in spec.reference_seeds
    ]
    if spec.protocol_check:
        try:
            half = kind_of(ref).halved_protocol(ref)
        except ParameterError as e:
            raise ParameterError(
                "StudySpec.protocol_check",
                True,
                "a reference whose rate and step can be halved (or protocol_check false)",
                str(e),
            ) from None
        out += [
            PlannedRun(
                run_key(ref.radius, None, seed, protocol=True),
                ref.radius,
                None,
                seed,
                replace(half, seed=seed),
                protocol=True,
            )
            for seed in spec.reference_seeds[: spec.protocol_seeds]
        ]
    for seed in spec.seeds:
        for r in spec.coarse_radii:
            for rule in spec.rules:
                test = replace(coarse[r, rule.name], seed=seed)
                out.append(PlannedRun(run_key(r, rule, seed), r, rule, seed, test))
            if r in controls:
                test = replace(controls[r], seed=seed)
                out.append(PlannedRun(run_key(r, None, seed, True), r, None, seed, test, True))
    return StudyPlan(spec, tuple(out))


def as_plan(study: StudyPlan | StudySpec) -> StudyPlan:
    """``study`` if it is a plan, else its :func:`plan`."""
    return study if isinstance(study, StudyPlan) else plan(study)


def cost_weights(planned: list[PlannedRun], reserve: float = 0.0) -> np.ndarray:
    """Each run's share of the runs' estimated particle-steps plus ``reserve`` (the most a
    ``decide`` study may still add, :func:`most_added`) [-]."""
    cost = np.array([p.particle_steps for p in planned])
    return cost / (cost.sum() + reserve)


def stored_plan_runs(study: StudyPlan | StudySpec, keys) -> list[PlannedRun]:
    """The plan's runs, then each run named in ``keys`` that is a planned run of the study
    (its reference or one of its variants) with another seed, in the order of ``keys``:
    what a report judges when a study's stored runs go beyond what its adaptive rule asks
    for now (runs added by an earlier rule, or by hand). Keys of no run of the study are
    left out."""
    study = as_plan(study)
    runs = list(study.runs)
    have = {p.key for p in runs}
    prefixes: dict[str, PlannedRun] = {}
    for p in runs:
        prefixes.setdefault(p.key.rpartition("-s")[0], p)
    for k in keys:
        prefix, _, seed = k.rpartition("-s")
        if k in have or not seed.isdigit() or prefix not in prefixes:
            continue
        run = prefixes[prefix].with_seed(int(seed))
        if run.key == k:
            runs.append(run)
            have.add(k)
    return runs


#: The adaptive loop's names, importable from here as before (engine.study.loop,
#: engine.study.stopping): the plan is static, and these replay or judge a study's rounds.
_LOOP_NAMES = {
    "plan_runs": "loop",
    "adaptive_summary": "loop",
    "final_look": "stopping",
    "most_added": "stopping",
}


def __getattr__(name: str):
    if name in _LOOP_NAMES:
        import importlib

        return getattr(importlib.import_module(f".{_LOOP_NAMES[name]}", __package__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
