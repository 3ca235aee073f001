"""Scaling (coarse-graining) studies: a fine reference and coarse variants under scaling rules,
each compared with the reference and priced in run time (PHYSICS.md section 5).

:class:`StudySpec` says what to run; :func:`run_study` runs it and answers with a
:class:`StudyResult`: curves of every run, the error table against the reference next to each
run's wall time and speed-up, the spread over seeds, and an advisor (coarsest radius within
tolerance per rule, best-fitting adhesion exponent).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from .errors import ParameterError, StopRequested
from .materials import BilinearAdhesive
from .metrics import ERROR_NAMES, run_errors
from .uniaxial import (
    GRAVITY,
    Progress,
    UniaxialResult,
    UniaxialTest,
    preset,
    run_uniaxial,
)

#: Units of the columns of :attr:`StudyResult.table`.
TABLE_UNITS = {
    "run": "",
    "radius": "m",
    "rule": "",
    "seed": "",
    "scale": "1",
    "particles": "1",
    "steps": "1",
    "dt": "s",
    "wall_time": "s",
    "particle_steps": "1",
    "speedup": "1",
    **dict.fromkeys(ERROR_NAMES, "1"),
}

_DT_POLICIES = ("fixed", "scaled")
_NAMED_RULES = {
    "paper": (1.0, 2.0),  # Thakur et al. 2013: stiffness ~ R, adhesion ~ R^2
    "unscaled": (0.0, 0.0),
    "linear_adhesion": (1.0, 1.0),
    "cubic_adhesion": (1.0, 3.0),
}


@dataclass(frozen=True)
class ScalingRule:
    """How the pair-law parameters follow the radius, with s = R / R_ref.

    Attributes:
        name: label of the rule (used in run keys and plots).
        stiffness_exponent: a in K1, K2, Kt, kadh ~ s^a [-], in [-1, 4].
        adhesion_exponent: b in f0 ~ s^b [-], in [-1, 5].
        dt: ``"fixed"`` (the reference's time step) or ``"scaled"`` (reference dt times s).
    """

    name: str
    stiffness_exponent: float = 1.0
    adhesion_exponent: float = 2.0
    dt: str = "fixed"

    def __post_init__(self) -> None:
        o = "ScalingRule"
        if not isinstance(self.name, str) or not self.name or len(self.name) > 40 or not all(
            c.isalnum() or c in "_-." for c in self.name
        ):
            raise ParameterError(f"{o}.name", self.name,
                                 "1 to 40 characters among letters, digits, '_', '-', '.'")
        for fname, lo, hi in (("stiffness_exponent", -1.0, 4.0), ("adhesion_exponent", -1.0, 5.0)):
            v = getattr(self, fname)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not lo <= v <= hi:
                raise ParameterError(f"{o}.{fname}", v, f"a number in [{lo:g}, {hi:g}]")
            object.__setattr__(self, fname, float(v))
        if self.dt not in _DT_POLICIES:
            raise ParameterError(f"{o}.dt", self.dt, "'fixed' or 'scaled'")

    @classmethod
    def named(cls, name: str, dt: str = "fixed") -> ScalingRule:
        """A named rule: ``paper`` (a = 1, b = 2), ``unscaled`` (a = b = 0),
        ``linear_adhesion`` (a = 1, b = 1), ``cubic_adhesion`` (a = 1, b = 3)."""
        if name not in _NAMED_RULES:
            raise ParameterError("ScalingRule.name", name, f"one of {sorted(_NAMED_RULES)}")
        a, b = _NAMED_RULES[name]
        return cls(name, a, b, dt)

    def apply(self, reference: UniaxialTest, radius: float, reference_dt: float) -> UniaxialTest:
        """The test of ``reference`` with particles of ``radius`` [m] and the pair law scaled
        by this rule. The platen (Hertz) law is unchanged: it is already stress-similar."""
        s = radius / reference.radius
        law = reference.pair_law.scaled(s, self.stiffness_exponent, self.adhesion_exponent)
        dt = reference_dt * (s if self.dt == "scaled" else 1.0)
        return replace(reference, radius=radius, pair_law=law, dt=dt)


@dataclass(frozen=True)
class PlannedRun:
    """One run of a study: ``key``, ``radius`` [m], ``rule`` (None for the reference),
    ``seed`` and its ``test`` (for coarse runs the time step is set once the reference has
    chosen its own)."""

    key: str
    radius: float
    rule: ScalingRule | None
    seed: int
    test: UniaxialTest


def run_key(radius: float, rule: ScalingRule | None, seed: int) -> str:
    """Key of a run, e.g. ``ref-s1`` or ``r5mm-paper-s1``."""
    if rule is None:
        return f"ref-s{seed}"
    return f"r{radius * 1e3:g}mm-{rule.name}-s{seed}"


@dataclass(frozen=True)
class StudySpec:
    """A scaling study.

    Attributes:
        reference: the fine reference test (its radius is R_ref and its pair law the
            reference parameters; must be a :class:`engine.BilinearAdhesive` law).
        coarse_radii: radii of the coarse variants [m], each != the reference radius.
        rules: scaling rules applied to every coarse radius (names unique).
        seeds: packing seeds; every seed runs the reference and all variants (default: the
            reference's seed).
        tolerance: error tolerance of the advisor (largest accepted error) [-], in (0, 1].
    """

    reference: UniaxialTest = field(default_factory=lambda: preset("quick"))
    coarse_radii: tuple[float, ...] = (5e-3,)
    rules: tuple[ScalingRule, ...] = field(
        default_factory=lambda: (ScalingRule.named("paper"), ScalingRule.named("unscaled")))
    seeds: tuple[int, ...] | None = None
    tolerance: float = 0.15

    def __post_init__(self) -> None:
        o = "StudySpec"
        if not isinstance(self.reference, UniaxialTest):
            raise ParameterError(f"{o}.reference", self.reference, "an engine.UniaxialTest")
        if not isinstance(self.reference.pair_law, BilinearAdhesive):
            raise ParameterError(f"{o}.reference.pair_law", type(self.reference.pair_law).__name__,
                                 "a BilinearAdhesive law (the scaling rules act on K1, K2, f0)")
        radii = tuple(self.coarse_radii)
        if not 1 <= len(radii) <= 8:
            raise ParameterError(f"{o}.coarse_radii", radii, "1 to 8 radii")
        r_ref = self.reference.radius
        for i, r in enumerate(radii):
            f = f"{o}.coarse_radii[{i}]"
            if isinstance(r, bool) or not isinstance(r, (int, float)) or not math.isfinite(r):
                raise ParameterError(f, r, "a finite number of metres")
            if not 0 < r <= 4 * r_ref or abs(r - r_ref) <= 1e-9 * r_ref:
                raise ParameterError(f, r, f"in (0, {4 * r_ref:g}] m (4 reference radii) and "
                                     f"different from the reference radius {r_ref:g} m")
        if len(set(radii)) != len(radii):
            raise ParameterError(f"{o}.coarse_radii", radii, "distinct radii")
        object.__setattr__(self, "coarse_radii", tuple(float(r) for r in radii))
        rules = tuple(self.rules)
        if not 1 <= len(rules) <= 8 or not all(isinstance(r, ScalingRule) for r in rules):
            raise ParameterError(f"{o}.rules", rules, "1 to 8 engine.ScalingRule")
        if len({r.name for r in rules}) != len(rules):
            raise ParameterError(f"{o}.rules", [r.name for r in rules], "rules with unique names")
        object.__setattr__(self, "rules", rules)
        seeds = (self.reference.seed,) if self.seeds is None else tuple(self.seeds)
        if not 1 <= len(seeds) <= 10 or len(set(seeds)) != len(seeds) or not all(
            isinstance(s, int) and not isinstance(s, bool) and 0 <= s < 2**31 for s in seeds
        ):
            raise ParameterError(f"{o}.seeds", seeds, "1 to 10 distinct integers in [0, 2^31)")
        object.__setattr__(self, "seeds", seeds)
        t = self.tolerance
        if isinstance(t, bool) or not isinstance(t, (int, float)) or not 0 < t <= 1:
            raise ParameterError(f"{o}.tolerance", t, "in (0, 1]")
        # every coarse test must itself be runnable: the cell holds the coarse radius, the
        # scaled adhesion and the (fixed or scaled) time step are within the engine's limits
        dt_ref = self.reference.resolved_dt()
        for i, r in enumerate(self.coarse_radii):
            for rule in self.rules:
                try:
                    rule.apply(self.reference, r, dt_ref)
                except ParameterError as e:
                    raise ParameterError(f"{o}.coarse_radii[{i}]", r,
                                         "a radius the reference's cell and laws can run",
                                         f"with rule {rule.name!r}: {e}") from None

    def planned_runs(self) -> list[PlannedRun]:
        """Every run, the reference of each seed first."""
        out = []
        dt_ref = self.reference.resolved_dt()
        for seed in self.seeds:
            ref = replace(self.reference, seed=seed)
            out.append(PlannedRun(run_key(ref.radius, None, seed), ref.radius, None, seed, ref))
            for r in self.coarse_radii:
                for rule in self.rules:
                    test = rule.apply(ref, r, dt_ref)
                    out.append(PlannedRun(run_key(r, rule, seed), r, rule, seed, test))
        return out

    def max_particles(self) -> int:
        """The largest particle count of any run."""
        return max(p.test.n_particles for p in self.planned_runs())

    def estimated_particle_steps(self) -> float:
        """Estimate of the study's total particle-steps (for admission limits)."""
        return float(sum(_estimated_steps(p.test) * p.test.n_particles
                         for p in self.planned_runs()))

    def to_dict(self) -> dict:
        """JSON-friendly form (inverse: :meth:`from_dict`)."""
        return {
            "reference": self.reference.to_dict(),
            "coarse_radii": list(self.coarse_radii),
            "rules": [{"name": r.name, "stiffness_exponent": r.stiffness_exponent,
                       "adhesion_exponent": r.adhesion_exponent, "dt": r.dt}
                      for r in self.rules],
            "seeds": list(self.seeds),
            "tolerance": self.tolerance,
        }

    @classmethod
    def from_dict(cls, d: dict) -> StudySpec:
        """Build from :meth:`to_dict` output. ``reference`` may hold ``"preset": "quick"``
        (or ``"paper"``) with overrides; rules may be given by name only."""
        d = dict(d)
        known = {"reference", "coarse_radii", "rules", "seeds", "tolerance"}
        if set(d) - known:
            raise ParameterError("StudySpec", sorted(set(d) - known),
                                 f"fields among {sorted(known)}")
        ref = d.get("reference", {"preset": "quick"})
        if isinstance(ref, dict):
            ref = dict(ref)
            name = ref.pop("preset", None)
            if name is not None:
                base = preset(name).to_dict()
                base.update(ref)
                ref = base
            d["reference"] = UniaxialTest.from_dict(ref)
        for k in ("coarse_radii", "rules", "seeds"):
            if k == "seeds" and d.get(k, ()) is None:
                del d[k]  # null: the reference's seed
            elif k in d and not isinstance(d[k], (list, tuple)):
                raise ParameterError(f"StudySpec.{k}", d[k], "a list")
        if "rules" in d:
            rules = []
            for i, r in enumerate(d["rules"]):
                if isinstance(r, str):
                    rules.append(ScalingRule.named(r))
                elif isinstance(r, dict):
                    try:
                        rules.append(ScalingRule(**r))
                    except TypeError as e:
                        raise ParameterError(f"StudySpec.rules[{i}]", r, "fields name, "
                                             "stiffness_exponent, adhesion_exponent, dt") from e
                else:
                    rules.append(r)
            d["rules"] = tuple(rules)
        for k in ("coarse_radii", "seeds"):
            if k in d:
                d[k] = tuple(d[k])
        return cls(**d)


def default_study() -> StudySpec:
    """The study the main job runs: the ``quick`` cohesive reference (R = 2.5 mm,
    f0 = -0.4 N) against R = 3.75 and 5 mm with the paper's rule and unscaled parameters."""
    ref = preset("quick", pair_law=BilinearAdhesive(k1=5e3, k2=2.5e4, f0=-0.4, mu_s=0.5,
                                                    mu_r=0.001, restitution=0.4))
    return StudySpec(reference=ref, coarse_radii=(3.75e-3, 5e-3),
                     rules=(ScalingRule.named("paper"), ScalingRule.named("unscaled")))


def _estimated_steps(test: UniaxialTest) -> float:
    """Rough step count of a test: fill (two free-fall times of the cell), compression of a
    bed of about 0.6 solid fraction by 10 % there and back, release, unconfined strain."""
    dt = test.resolved_dt()
    height = test.cell[2] * test.fill_fraction / 0.6
    t = 2 * math.sqrt(2 * test.cell[2] / GRAVITY) + 0.2 * height / test.platen_speed
    if test.unconfined:
        t += test.release_time + test.max_unconfined_strain * height / test.platen_speed
    return t / dt


@dataclass(frozen=True)
class StudyProgress:
    """What a study progress callback receives: overall ``fraction`` in [0, 1], the run
    (``run_index`` of ``n_runs``, ``run_key``), its ``stage`` and simulated ``time`` [s]."""

    fraction: float
    run_index: int
    n_runs: int
    run_key: str
    stage: str
    time: float
    message: str = ""


@dataclass
class RunResult:
    """One finished run: its key, radius [m], rule (None for the reference), seed, the
    :class:`UniaxialResult`, and its errors against the reference of its seed (zeros for
    the reference itself), its speed-up over that reference and its scale s = R / R_ref."""

    key: str
    radius: float
    rule: ScalingRule | None
    seed: int
    result: UniaxialResult
    errors: dict[str, float]
    speedup: float = 1.0
    scale: float = 1.0

    def row(self) -> dict:
        """The run's row of the study table."""
        s = self.result.scalars
        return {
            "run": self.key, "radius": self.radius,
            "rule": "reference" if self.rule is None else self.rule.name, "seed": self.seed,
            "scale": self.scale,
            "particles": int(s["particles"]), "steps": int(s["steps"]), "dt": s["dt"],
            "wall_time": s["wall_time"], "particle_steps": s["particle_steps"],
            "speedup": self.speedup, **self.errors,
        }


@dataclass
class StudyResult:
    """Result of :func:`run_study`: ``runs`` (key -> :class:`RunResult`, each seed's
    reference first), ``table`` (one row per run, units in :data:`TABLE_UNITS`), ``groups``
    (mean and spread over seeds per radius and rule) and ``advisor``."""

    spec: StudySpec
    runs: dict[str, RunResult]
    table: list[dict]
    groups: list[dict]
    advisor: dict

    def to_summary(self) -> dict:
        """JSON-friendly summary: table, groups, advisor and units."""
        return {"table": self.table, "groups": self.groups, "advisor": self.advisor,
                "units": TABLE_UNITS}

    def figure(self, kind: str):
        """A matplotlib Figure (no pyplot) of ``kind`` in :data:`engine.plots.KINDS`."""
        from .plots import figure, study_plot_data

        return figure(kind, *study_plot_data(self))

    def save_plots(self, directory) -> list:
        """Write every plot kind as PNG into ``directory``; returns the paths."""
        from .plots import save_all, study_plot_data

        return save_all(directory, *study_plot_data(self))


StudyCallback = Callable[[StudyProgress], object]


class RunFailed(RuntimeError):
    """A run of a study failed (its stage did not end, or it went unstable); ``run_key``
    names it and ``__cause__`` holds the engine's error."""

    def __init__(self, run_key: str, error: Exception):
        self.run_key = run_key
        super().__init__(f"run {run_key} failed: {type(error).__name__}: {error}")


def run_study(spec: StudySpec, progress: StudyCallback | None = None) -> StudyResult:
    """Run every run of ``spec`` (each seed's reference first, then its coarse variants) and
    compare each coarse run with the reference of its seed.

    Coarse runs with ``dt="fixed"`` take the reference's time step; ``"scaled"`` multiplies it
    by s = R / R_ref. ``progress`` receives :class:`StudyProgress`; returning ``False``
    stops the study with :class:`engine.StopRequested`.

    Raises: :class:`RunFailed` when a run fails (the engine's error is its cause).
    """
    planned = spec.planned_runs()
    cost = np.array([_estimated_steps(p.test) * p.test.n_particles for p in planned])
    start = np.concatenate([[0.0], np.cumsum(cost)]) / cost.sum()
    runs: dict[str, RunResult] = {}
    refs: dict[int, RunResult] = {}
    for i, p in enumerate(planned):
        test = p.test
        if p.rule is not None:
            ref_run = refs[p.seed]
            test = p.rule.apply(ref_run.result.test, p.radius, ref_run.result.scalars["dt"])

        def report(pr: Progress, i=i, p=p):
            if progress is None:
                return None
            frac = start[i] + (start[i + 1] - start[i]) * pr.fraction
            return progress(StudyProgress(float(min(frac, 1.0)), i, len(planned), p.key,
                                          pr.stage, pr.time, pr.message))

        # a first report names the run before its packing and kernels are built, so a run
        # that fails there is not blamed on the previous one
        if report(Progress(0.0, "setup", 0.0, 0.0, 0, "building the packing")) is False:
            raise StopRequested(f"stopped by the progress callback before run {p.key}")
        try:
            res = run_uniaxial(test, progress=report)
        except StopRequested:
            raise
        except Exception as e:
            raise RunFailed(p.key, e) from e
        if p.rule is None:
            errors = dict.fromkeys(_error_names(spec), 0.0)
            rr = RunResult(p.key, p.radius, None, p.seed, res, errors, 1.0, 1.0)
            refs[p.seed] = rr
        else:
            ref_res = refs[p.seed].result
            try:
                errors = run_errors(res, ref_res)
            except ValueError as e:
                raise RunFailed(p.key, e) from e
            rr = RunResult(p.key, p.radius, p.rule, p.seed, res, errors,
                           ref_res.scalars["wall_time"] / res.scalars["wall_time"],
                           p.radius / spec.reference.radius)
        runs[p.key] = rr
    table = [r.row() for r in runs.values()]
    groups = _groups(spec, runs)
    ref_strength = None
    if spec.reference.unconfined:
        ref_strength = float(np.mean([r.result.scalars["unconfined_strength"]
                                      for r in refs.values()]))
    return StudyResult(spec, runs, table, groups, advise(spec, groups, ref_strength))


def _error_names(spec: StudySpec) -> tuple[str, ...]:
    return ERROR_NAMES if spec.reference.unconfined else ERROR_NAMES[:-1]


def _groups(spec: StudySpec, runs: dict[str, RunResult]) -> list[dict]:
    """Mean and spread (sample standard deviation; 0 with one seed) over seeds of the
    errors, wall time and speed-up of every (radius, rule)."""
    out = []
    names = _error_names(spec)
    for r in spec.coarse_radii:
        for rule in spec.rules:
            members = [x for x in runs.values() if x.rule == rule and x.radius == r]
            g = {"radius": r, "rule": rule.name, "scale": r / spec.reference.radius,
                 "stiffness_exponent": rule.stiffness_exponent,
                 "adhesion_exponent": rule.adhesion_exponent, "dt": rule.dt,
                 "seeds": len(members)}
            cols = {n: [m.errors[n] for m in members] for n in names}
            cols["wall_time"] = [m.result.scalars["wall_time"] for m in members]
            cols["speedup"] = [m.speedup for m in members]
            if spec.reference.unconfined:
                cols["unconfined_strength"] = [m.result.scalars["unconfined_strength"]
                                               for m in members]
            for n, v in cols.items():
                g[n] = float(np.mean(v))
                g[n + "_std"] = float(np.std(v, ddof=1)) if len(v) > 1 else 0.0
            g["max_error"] = max(g[n] for n in names)
            out.append(g)
    return out


def advise(spec: StudySpec, groups: list[dict], reference_strength: float | None = None
           ) -> dict:
    """Per rule, the coarsest radius whose largest mean error is within the tolerance; and,
    when rules differ only in their adhesion exponent, the best-fitting exponent per radius.

    The fitted exponent solves log(strength(b)) = log(reference strength) on the
    least-squares line of log strength against b (strength ~ s^(b - b*) for a bed whose
    strength scales with the contact adhesion); with fewer than two positive strengths it is
    omitted and only the best exponent among those run is given.
    """
    tol = spec.tolerance
    rules = {}
    for rule in spec.rules:
        ok = [g for g in groups if g["rule"] == rule.name and g["max_error"] <= tol]
        best = max(ok, key=lambda g: g["radius"]) if ok else None
        rules[rule.name] = {
            "coarsest_radius": best["radius"] if best else None,
            "max_error": best["max_error"] if best else None,
            "speedup": best["speedup"] if best else None,
            "radii_within_tolerance": sorted(g["radius"] for g in ok),
        }
    lines = []
    for name, a in rules.items():
        if a["coarsest_radius"] is None:
            lines.append(f"{name}: no coarse radius within {tol:.0%}")
        else:
            lines.append(f"{name}: up to R = {a['coarsest_radius'] * 1e3:g} mm "
                         f"(largest error {a['max_error']:.1%}, {a['speedup']:.1f}x faster)")
    adhesion = _adhesion_advice(spec, groups, reference_strength)
    if adhesion:
        for r, v in adhesion["by_radius"].items():
            fit = f", fitted b = {v['fitted']:.2f}" if v.get("fitted") is not None else ""
            lines.append(f"adhesion exponent at R = {float(r) * 1e3:g} mm: best run b = "
                         f"{v['best']:g}{fit}")
    return {"tolerance": tol, "rules": rules, "adhesion_exponent": adhesion,
            "message": "; ".join(lines)}


def _adhesion_advice(spec: StudySpec, groups: list[dict], reference_strength: float | None
                     ) -> dict | None:
    if not spec.reference.unconfined:
        return None
    # rules that share stiffness exponent and dt policy but differ in adhesion exponent
    families: dict[tuple, set] = {}
    for rule in spec.rules:
        families.setdefault((rule.stiffness_exponent, rule.dt), set()).add(rule.adhesion_exponent)
    family = max(families.items(), key=lambda kv: len(kv[1]))
    if len(family[1]) < 2:
        return None
    a, dt = family[0]
    by_radius = {}
    for r in spec.coarse_radii:
        gs = [g for g in groups if g["radius"] == r and g["stiffness_exponent"] == a
              and g["dt"] == dt]
        best = min(gs, key=lambda g: g["err_strength"])
        entry = {"best": best["adhesion_exponent"], "err_strength": best["err_strength"],
                 "fitted": None}
        pts = [(g["adhesion_exponent"], g["unconfined_strength"]) for g in gs
               if g.get("unconfined_strength", 0.0) > 0]
        if reference_strength and reference_strength > 0 and len({b for b, _ in pts}) >= 2:
            b, strength = np.array(pts).T
            slope, icept = np.polyfit(b, np.log(strength), 1)
            if slope > 0:
                entry["fitted"] = float((math.log(reference_strength) - icept) / slope)
        by_radius[f"{r:g}"] = entry
    return {"stiffness_exponent": a, "dt": dt, "by_radius": by_radius}
