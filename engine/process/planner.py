"""How coarse a user can go for a process: the planner (docs/PHYSICS.md section 7.7).

For the bilinear law with K ~ R and f0 ~ R^2 (and EEPA with K ~ R^(2-n)) coarse-graining by
a factor s is an exact similarity (:mod:`engine.core.similarity`): a coarse model of a
feature L wide is the fine law in a feature L / s wide. So a coarse model keeps a property
of the feature within its tolerance while the feature spans at least N_req coarse
particles, the fine law's own size effect, measured per feature kind by the size series
(``python -m benchmarks.size_series``; their answer is stored in ``evidence.json`` beside
this module):

    s_max = L / (N_req d0)

for a powder of diameter d0. N_req holds for the law it was measured with at the stress it
was measured at: the evidence applies to a user's law when its dimensionless groups at the
process's stress match a stored series' (:data:`MATCH_TOLERANCE`): the stiffness number
k1 / (sigma d), the cohesion number |f0| / (sigma d^2), K2 / K1, kt / K1, the friction and
rolling coefficients and the restitution. Nothing is inferred for a law, a stress or a
feature kind without a series; the plan says which series would decide it and its cost.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..contact.bilinear import BilinearAdhesive
from ..contact.eepa import EEPA
from ..contact.hertz import HertzMindlin
from ..contact.registry import law_names, pair_laws
from ..core.errors import ParameterError
from ..core.records import Record, check_fields, from_dict, param, to_dict
from ..core.similarity import similar
from ..io.liggghts import to_liggghts
from ..study.resolution import point_words

EVIDENCE = Path(__file__).with_name("evidence.json")

#: Feature kinds a plan answers for, and what each stands for.
FEATURE_KINDS = {
    "bulk_compression": "bulk in confined compression (density, stiffness, coordination)",
    "bulk_shear": "bulk in shear (yield locus, sigma_1, sigma_c, ffc, bulk density)",
    "free_surface": "a free surface (the unconfined strength of a released column)",
    "outlet": "a hopper or silo outlet (discharge rate, arching)",
}
#: The dimensionless groups that must match a stored series' for its N_req to apply, each
#: within this relative tolerance: fixed on 2026-12-06 before any user law was planned. A
#: size effect changes smoothly with these groups, but how fast is not measured; 10 % is
#: the resolution at which the two stored laws differ (f0 x 3) by thirty times over.
MATCH_TOLERANCE = 0.10
#: The engine's throughput on one core [particle-steps/s], for a coarse run's cost (the
#: size series' columns: 2.0-2.3e6 on this project's 2-core machine, benchmarks.size_series).
THROUGHPUT = 2.0e6


@dataclass(frozen=True)
class Process(Record):
    """A process to coarse-grain (SI units).

    Attributes:
        pair_law: the fine powder's particle-particle law, for particles of ``diameter``.
        diameter: the fine particle diameter d0 [m].
        density: the particle density [kg/m^3].
        feature_width: the width L of the process's smallest feature [m] (an outlet's
            width, a channel's, a layer's thickness).
        feature_kind: what the feature is: one of :data:`FEATURE_KINDS`.
        stress: the stress level in the feature [Pa]; None: the weight of a column of bulk
            as tall as the feature is wide, solid_fraction rho g L.
        velocity: the process's velocity scale [m/s] (a flow speed, a blade's tip speed):
            with L it sets the strain rate V / L of the inertial number.
        gravity: the acceleration of gravity [m/s^2].
        solid_fraction: the bulk's solid fraction [-] (particles per volume).
        volume: the volume of material the process simulates [m^3], for a run's cost.
        duration: the process time a run simulates [s], for a run's cost.
    """

    pair_law: BilinearAdhesive | EEPA | HertzMindlin = param(
        unit="", kind="record", types=pair_laws, doc="the fine powder's pair law at diameter"
    )
    diameter: float = param(unit="m", ge=1e-8, le=0.1, doc="fine particle diameter d0")
    feature_width: float = param(
        unit="m", gt=0, le=100.0, doc="width of the smallest feature (>= diameter)"
    )
    feature_kind: str = param(
        "bulk_shear",
        unit="",
        kind="str",
        choices=tuple(FEATURE_KINDS),
        doc="the feature's kind",
    )
    density: float = param(2000.0, unit="kg/m^3", ge=1.0, le=1e5, doc="particle density")
    stress: float | None = param(
        None,
        unit="Pa",
        ge=1e-3,
        le=1e9,
        nullable=True,
        doc="stress in the feature (None: solid_fraction rho g L)",
    )
    velocity: float = param(0.1, unit="m/s", ge=1e-9, le=1e3, doc="the process's velocity scale")
    gravity: float = param(9.81, unit="m/s^2", ge=0, le=1e4, doc="acceleration of gravity")
    solid_fraction: float = param(0.6, unit="1", gt=0, le=0.74, doc="solid fraction of the bulk")
    volume: float = param(1e-3, unit="m^3", ge=1e-15, le=1e6, doc="volume of material simulated")
    duration: float = param(1.0, unit="s", ge=1e-9, le=1e6, doc="process time simulated")

    def __post_init__(self) -> None:
        o = "Process"
        if not isinstance(self.pair_law, pair_laws()):
            raise ParameterError(f"{o}.pair_law", self.pair_law, f"an {law_names(pair_laws())}")
        check_fields(self, o)
        if self.feature_width < self.diameter:
            raise ParameterError(
                f"{o}.feature_width",
                self.feature_width,
                f">= diameter = {self.diameter:g} m",
                "a feature narrower than one fine particle",
            )
        if self.stress is None and self.gravity == 0:
            raise ParameterError(
                f"{o}.stress", None, "given", "without gravity the feature's stress is not set"
            )
        if getattr(self.pair_law, "similarity_exponents", None) is None:
            raise ParameterError(
                f"{o}.pair_law",
                type(self.pair_law).__name__,
                "an adhesive elasto-plastic law (BilinearAdhesive or EEPA)",
                "the planner scales a law by its exact similarity; a Hertz law has none "
                "declared here",
            )

    @property
    def feature_stress(self) -> float:
        """The feature's stress [Pa]: ``stress`` or solid_fraction rho g L."""
        if self.stress is not None:
            return self.stress
        return self.solid_fraction * self.density * self.gravity * self.feature_width


def groups(law, diameter: float, stress: float) -> dict[str, float]:
    """The dimensionless groups of a pair law for particles of ``diameter`` [m] at
    ``stress`` [Pa] that a size series holds: stiffness number k1 / (sigma d) (k1 d^(n-1)
    for EEPA), cohesion number |f0| / (sigma d^2), K2 / K1 and the law's dimensionless
    coefficients."""
    n = float(getattr(law, "n", 1.0))
    out = {
        "stiffness_number": law.k1 * (diameter / 2) ** (n - 1) / (stress * diameter),
        "cohesion_number": abs(law.f0) / (stress * diameter**2),
        "k2_over_k1": law.k2 / law.k1,
        "kt_ratio": law.kt_ratio,
        "mu_s": law.mu_s,
        "mu_r": law.mu_r,
        "restitution": law.restitution,
    }
    if hasattr(law, "kadh"):
        chi = float(getattr(law, "chi", 1.0))
        out["adhesive_number"] = law.kadh * (diameter / 2) ** (chi - 1) / (stress * diameter)
    if hasattr(law, "n"):
        out["n"] = n
        out["chi"] = float(getattr(law, "chi", 1.0))
    return out


def _mismatch(a: dict, b: dict) -> list[str]:
    """The groups of ``a`` that differ from ``b``'s by more than MATCH_TOLERANCE (relative;
    absolute for groups that are 0 in both)."""
    out = []
    for k in sorted(set(a) | set(b)):
        x, y = a.get(k), b.get(k)
        if x is None or y is None:
            out.append(k)
            continue
        if x == y:
            continue
        if abs(x - y) > MATCH_TOLERANCE * max(abs(x), abs(y)):
            out.append(k)
    return out


def load_evidence(path: Path = EVIDENCE) -> dict:
    """The stored evidence (generated by ``python -m benchmarks.size_report``)."""
    return json.loads(Path(path).read_text())


@dataclass
class FeaturePlan:
    """The answer for one feature kind (SI units).

    ``status``: "decided" (N_req from a matching series), "bounded" (only a bound: the
    finest size run was not enough, or every size held), "undecided" (the series has the
    kind but a property off its line or confounded), "not_measured"; ``n_req_point``
    and ``n_req_bound`` [particles across], ``bound`` as the series reports it;
    ``s_max_point`` and ``s_max`` [-] the factors they give (``s_max`` the one to use: from
    the 95 % bound; for "more_than" an upper limit: the admissible factor is below it;
    ``s_max_point`` no larger than the coarsest size run gives, where the point estimate
    lies below it: coarser is not measured);
    ``evidence`` the series' law name and the property that sets the need; ``why`` in words.
    """

    kind: str
    status: str
    why: str
    n_req_point: float | None = None
    n_req_bound: float | None = None
    bound: str | None = None
    s_max: float | None = None
    s_max_point: float | None = None
    limited_by: str | None = None
    evidence: str | None = None
    coarse: dict = field(default_factory=dict)


@dataclass
class ProcessPlan:
    """A :func:`plan_process` answer: the process, the fine law's groups, the series that
    match it, one :class:`FeaturePlan` per feature kind (the process's own first)."""

    process: Process
    groups: dict
    matched: str | None
    mismatches: dict
    features: list[FeaturePlan]

    @property
    def answer(self) -> FeaturePlan:
        """The plan of the process's own feature kind."""
        return self.features[0]

    def to_dict(self) -> dict:
        return {
            "process": to_dict(self.process),
            "feature_stress": self.process.feature_stress,
            "groups": self.groups,
            "matched_series": self.matched,
            "mismatches": self.mismatches,
            "features": [vars(f) for f in self.features],
        }


def _coarse(process: Process, s: float, series: dict | None = None) -> dict:
    """The coarse model at factor ``s``: the law scaled by the similarity, its diameter,
    time step, inertial and Bond numbers, particles per cubic metre and the cost of a
    run of the process's volume and duration."""
    from ..simulation.scene import Scene
    from ..simulation.timestep import critical_time_step

    d0 = process.diameter
    d = s * d0
    law = similar(process.pair_law, s)
    r = d / 2
    scene = Scene(
        np.array([[0.0, 0.0, 0.0], [4 * r, 0.0, 0.0]]),
        np.full(2, r),
        process.density,
        pair_law=law,
        gravity=(0.0, 0.0, -process.gravity),
    )
    lim = critical_time_step(scene, max(process.velocity, 0.1))
    dt = 0.4 * lim.dt  # the default protocol's fraction of the critical time
    sigma = process.feature_stress
    strain_rate = process.velocity / process.feature_width
    mass = process.density * math.pi * d**3 / 6
    per_m3 = process.solid_fraction / (math.pi * d**3 / 6)
    n = per_m3 * process.volume
    steps = process.duration / dt
    weight = mass * process.gravity
    inertial = strain_rate * d * math.sqrt(process.density / sigma)
    fine_inertial = inertial / s
    warnings = []
    held = (series or {}).get("inertial_number")
    if held and inertial > 2 * held:
        warnings.append(
            f"the coarse model's inertial number {inertial:.2g} (the fine powder's "
            f"{fine_inertial:.2g} times s) is above the {held:g} the size series held: "
            "N_req was measured quasi-static, and a rate effect at this inertial number is "
            "not measured"
        )
    if weight > 0:
        warnings.append(
            f"the similarity scales gravity by 1 / s, the process does not: the coarse "
            f"particle's Bond number |f0| / (m g) is the fine one's / s "
            f"({abs(process.pair_law.f0) / (weight / s**3):.3g} -> "
            f"{abs(law.f0) / weight:.3g}); a cohesive effect of the particles' own weight "
            "(arching under gravity, a free surface's slope) changes with it"
        )
    return {
        "factor": s,
        "diameter": d,
        "pair_law": to_dict(law),
        "time_step": dt,
        "time_step_limited_by": lim.reason,
        "inertial_number": inertial,
        "fine_inertial_number": fine_inertial,
        "bond_number": abs(law.f0) / weight if weight > 0 else math.inf,
        "cohesion_number": abs(law.f0) / (sigma * d**2),
        "particles_per_m3": per_m3,
        "particles": n,
        "particle_steps": n * steps,
        "core_hours": n * steps / THROUGHPUT / 3600,
        "speed_up": s**4,  # s^3 fewer particles, each step s times longer
        "liggghts": to_liggghts(law, note=f"coarse-grained x {s:.4g}", radius=r),
        "warnings": warnings,
    }


def _series_cost(process: Process) -> str:
    """What a series for this law would cost (the stored series' runs, scaled by the
    particle count only: the same sizes in diameters across)."""
    return (
        "a size series of this law (benchmarks/size_series.py with the law added to LAWS: "
        "columns 5-20 diameters across, 3-4 seeds a size, about 5 h on one core; the shear "
        "cell 2.5-15 diameters, about 1.5 h)"
    )


def plan_process(process: Process, evidence: dict | None = None) -> ProcessPlan:
    """The largest admissible coarse-graining factor for ``process`` per feature kind,
    with its evidence and the coarse model at that factor (module docstring)."""
    if not isinstance(process, Process):
        raise TypeError(f"plan_process takes an engine.Process, not {type(process).__name__}")
    ev = load_evidence() if evidence is None else evidence
    sigma = process.feature_stress
    try:
        g = groups(process.pair_law, process.diameter, sigma)
    except (ArithmeticError, ValueError):
        g = {"stiffness_number": math.nan}
    if not (sigma > 0 and all(math.isfinite(v) for v in g.values())):
        raise ParameterError(
            "Process.pair_law",
            type(process.pair_law).__name__,
            "a law whose dimensionless groups are finite at the feature's stress "
            f"({sigma:.3g} Pa) and diameter",
        )
    matched, same_law, mismatches = None, None, {}
    for name, law in ev.get("laws", {}).items():
        series_law = from_dict(type(process.pair_law), _strip_type(law["pair_law"]))
        theirs = groups(series_law, 2 * law["radius"], law["consolidation_stress"])
        if type(series_law) is not type(process.pair_law):
            mismatches[name] = ["law type"]
            continue
        off = _mismatch(g, theirs)
        # the same law up to the similarity: the groups match at the series' own stress
        mine = groups(process.pair_law, process.diameter, law["consolidation_stress"])
        if same_law is None and not _mismatch(mine, theirs):
            same_law = name
        if off:
            mismatches[name] = [
                f"{k} {g.get(k, math.nan):.3g} (series {theirs.get(k):.3g})" for k in off
            ]
        elif matched is None:
            matched = name
    kinds = [process.feature_kind] + [k for k in FEATURE_KINDS if k != process.feature_kind]
    features = []
    L, d0 = process.feature_width, process.diameter
    for kind in kinds:
        series, entry = _evidence_for(ev, kind, matched, same_law, sigma)
        if series is None:
            features.append(
                FeaturePlan(
                    kind,
                    "not_measured",
                    "no stored size series has this law's groups at the feature's stress "
                    f"({sigma:.3g} Pa); deciding it needs {_series_cost(process)}",
                )
            )
            continue
        if entry is None or entry.get("bound") in ("not_linear", "confounded", "stress"):
            if entry is not None and entry.get("bound") == "stress":
                why = entry["why"]
            elif entry is not None and entry.get("bound") == "confounded":
                what = entry.get("why", "a property is confounded")
                why = f"not decided: in series {series} {what} (docs/RESOLUTION.md, Confounds)"
            else:
                why = (
                    f"not measured: no {kind} size series of this law decides it (series "
                    f"{series}, docs/RESOLUTION.md)"
                )
            undecided = entry is not None and entry.get("bound") in ("not_linear", "confounded")
            status = "undecided" if undecided else "not_measured"
            features.append(FeaturePlan(kind, status, why, evidence=series))
            continue
        npt, nb, bound = entry["n_req_point"], entry["n_req_bound"], entry["bound"]
        coarsest = min(entry.get("sizes") or [npt])
        s_pt, s_b = L / (max(npt, coarsest) * d0), L / (nb * d0)
        if bound == "needs":
            status = "decided"
            why = (
                f"N_req: {point_words(npt, coarsest, ' particles across')} (95 % bound "
                f"{nb:.3g}), set by {entry['limited_by']} (series {series})"
            )
        elif bound == "more_than":
            status = "bounded"
            why = (
                f"N_req is more than {nb:.3g} particles across (the finest size measured; point "
                f"estimate {npt:.3g}), set by {entry['limited_by']}: the factor must be "
                f"below {s_b:.3g} (series {series})"
            )
        else:
            status = "bounded"
            why = (
                f"every property held down to {nb:.3g} particles across (the coarsest size "
                f"run; series {series}): a factor of {s_b:.3g} is safe, coarser not measured"
            )
        features.append(
            FeaturePlan(
                kind,
                status,
                why,
                n_req_point=npt,
                n_req_bound=nb,
                bound=bound,
                s_max=s_b,
                s_max_point=s_pt,
                limited_by=entry["limited_by"],
                evidence=series,
                coarse=_coarse(process, s_b, ev["laws"][series]) if s_b >= 1 else {},
            )
        )
    return ProcessPlan(process, g, matched, mismatches, features)


def _evidence_for(ev: dict, kind: str, matched, same_law, sigma: float):
    """The series and its entry that answer for feature ``kind``: an entry that states the
    stress each property's series held (``stresses``) is read by law (``same_law``: the
    groups match at the series' own stress) and kept to the properties that apply at
    ``sigma`` (:func:`_at_stress`); any other holds the series' consolidation stress, so it
    needs the groups to match at the feature's stress (``matched``). (None, None) where no
    series answers."""
    if same_law is not None:
        entry = ev["laws"][same_law]["features"].get(kind)
        if entry is not None and "stresses" in entry:
            return same_law, _at_stress(entry, sigma)
    if matched is None:
        return None, None
    return matched, ev["laws"][matched]["features"].get(kind)


def _at_stress(entry: dict | None, sigma: float) -> dict | None:
    """An outlet's need restricted to the properties that apply at the feature's stress
    ``sigma`` [Pa]: a property whose series held a stress (``entry["stresses"]``, e.g. the
    discharge at its held g B) applies within MATCH_TOLERANCE of it; one held at the law's
    own transition (None: the arching width) applies to the law at any stress. The need is
    the most demanding remaining property's; ``bound`` "stress" (with ``why``) where none
    remains."""
    if entry is None or "per_property" not in entry:
        return entry
    stresses = entry.get("stresses", {})
    keep, dropped = {}, []
    for name, need in entry["per_property"].items():
        held = stresses.get(name)
        if held is not None and abs(sigma - held) > MATCH_TOLERANCE * max(sigma, held):
            dropped.append(f"{name} (its series held {held:.3g} Pa)")
            continue
        keep[name] = need
    known = {n: v for n, v in keep.items() if v.get("diameters") is not None}
    if not known:
        return {
            "bound": "stress",
            "why": f"not measured at {sigma:.3g} Pa: " + "; ".join(dropped or ["no property"]),
        }
    name = max(known, key=lambda n: (known[n]["bound"] == "more_than", known[n]["diameters"]))
    out = dict(entry)
    out.update(
        limited_by=name,
        bound=known[name]["bound"],
        n_req_bound=known[name]["diameters"],
        n_req_point=max(v["point"] for v in known.values()),
        tolerance=known[name]["tolerance"],
        left_out_at_stress=dropped,
    )
    return out


def _strip_type(d: dict) -> dict:
    return {k: v for k, v in d.items() if k != "type"}


def answer_line(plan: ProcessPlan) -> str:
    """One line: the largest factor for the process's feature, and the others'."""
    p = plan.process

    def one(f: FeaturePlan) -> str:
        if f.status in ("not_measured", "undecided"):
            return f"{f.kind}: {f.status.replace('_', ' ')}"
        rel = {"more_than": "below ", "at_most": "at least "}.get(f.bound or "", "")
        fewer = {"more_than": "under ", "at_most": "at least "}.get(f.bound or "", "")
        speed = f"{fewer}{f.s_max**4:.3g}x fewer particle-steps" if f.s_max and f.s_max >= 1 else ""
        return f"{f.kind}: s_max {rel}{f.s_max:.3g}" + (f" ({speed})" if speed else "")

    head = (
        f"{p.diameter * 1e6:.4g} um powder, {p.feature_kind} {p.feature_width * 1e3:.4g} mm "
        f"wide at {p.feature_stress / 1e3:.3g} kPa"
    )
    return f"{head}: " + "; ".join(one(f) for f in plan.features)
