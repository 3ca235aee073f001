"""What a study can cost at worst, from its raw fields, before anything is built.

The admission refuses an oversized body from its fields, before the engine builds and checks
the study's records (which for hundreds of runs costs far more than these checks, in
microseconds per run). Everything here works on the request's fields and on *probes*
(records whose fields are set without their checks):

- :func:`plan_counts`: the number of runs (seeds x (1 + radii x rules), + seeds x radii
  resolution controls);
- :func:`work_bounds`: the bounds on the knobs that set a run's work or output, relative
  to its time step and to its stages' physics (:data:`BOUNDS`);
- :func:`worst_stage_times`: the longest simulated time each stage can take, as the engine
  bounds it (``max_stage_time`` for every stage, and what each stage's physics adds: the
  platen cannot travel further than the pour column, a hold ends only by coming to rest
  (``max_stage_time``), the release ends at ``release_time``,
  unconfined compression at ``max_unconfined_strain``);
- :func:`worst_case`: particle-steps and curve samples of every planned run at those times,
  which the admission caps compare (``DEMSCALE_MAX_PARTICLE_STEPS``,
  ``DEMSCALE_MAX_CURVE_SAMPLES``).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import engine
from engine.contact.registry import LAWS
from engine.contact.wall import WallMaterial
from engine.uniaxial.spec import PRESETS, PROTOCOLS

#: Bounds on the knobs that set work, as the admission enforces them (docs/SERVICE.md).
BOUNDS = {
    "output_interval": "in [dt, 0.01 x H / platen_speed]: at most one curve sample a time "
    "step, at least one per 1 % of axial strain",
    "max_stage_time": "<= 10 x max(2 free-fall times of the pour column, pour column / "
    "platen_speed)",
    "settle_ke": ">= 1e-8 (below that the fill never settles: it runs to max_stage_time)",
}
#: Smallest ``settle_ke`` admitted [-] (also declared in the OpenAPI document).
MIN_SETTLE_KE = 1e-8
#: ``max_stage_time`` at most this many times the stage's own time scale.
STAGE_TIME_FACTOR = 10.0
#: ``output_interval`` at most the time of this much axial strain at the platen speed.
SAMPLE_STRAIN = 0.01


def _preset_fields() -> dict[tuple[str, str], dict]:
    """The presets' fields at each protocol (each built once, when this module is imported)."""
    return {(n, p): engine.preset(n, p).to_dict() for n in PRESETS for p in PROTOCOLS}


_PRESETS = _preset_fields()


def reference_fields(data: dict) -> dict:
    """The reference test's fields as the engine will build them: the preset (``quick``
    when no reference is given) or the record's defaults, overridden by the request; a
    shear reference's (``"type": "ShearTest"``): engine.ShearTest's defaults, overridden (a
    hopper's, ``"HopperTest"``, engine.HopperTest's)."""
    given = dict(data.get("reference", {"preset": "quick"}))
    test_type = given.pop("type", "UniaxialTest")
    if test_type == "ShearTest":  # a shear study's reference
        return {**_defaults(engine.ShearTest), **given}
    if test_type == "HopperTest":  # a hopper study's
        return {**_defaults(engine.HopperTest), **given}
    name = given.pop("preset", None)
    protocol = given.pop("protocol", "default")
    protocol = protocol if protocol in PROTOCOLS else "default"  # the schema refuses others
    if name is not None:
        base = dict(_PRESETS[(name, protocol)])
    else:
        base = _defaults(engine.UniaxialTest)
        if protocol == "seed":
            base.update(engine.SEED_PROTOCOL)
    return {**base, **given}


def _defaults(cls: type) -> dict:
    """The record ``cls``'s default field values."""
    return {
        f.name: f.default if f.default_factory is dataclasses.MISSING else f.default_factory()
        for f in dataclasses.fields(cls)
    }


def _law(value, default: str):
    if not isinstance(value, dict):
        return value
    value = dict(value)
    kind = value.pop("type", default)
    cls = LAWS[kind]
    return cls(**value)


def probe(fields: dict, **changes) -> engine.UniaxialTest:
    """A :class:`engine.UniaxialTest` with ``fields`` (and ``changes``) set but not
    validated: for its derived quantities (``n_particles``, ``pour_height``,
    ``time_step_limit()``) on a request whose worst case is refused before the engine's
    checks run (a field the engine would refuse is named by the engine afterwards). The laws
    are built (and check themselves)."""
    values = {**fields, **changes}
    values["pair_law"] = _law(values.get("pair_law"), "BilinearAdhesive")
    values["wall_law"] = _law(values.get("wall_law"), "HertzMindlin")
    if isinstance(values.get("wall_material"), dict):
        values["wall_material"] = WallMaterial(**values["wall_material"])
    out = object.__new__(engine.UniaxialTest)
    for name, value in values.items():
        object.__setattr__(out, name, tuple(value) if isinstance(value, list) else value)
    return out


def _rules(data: dict) -> list[engine.ScalingRule]:
    given = data.get("rules")
    if given is None:
        field = next(f for f in dataclasses.fields(engine.StudySpec) if f.name == "rules")
        return list(field.default_factory())
    out = []
    for r in given:
        if isinstance(r, engine.ScalingRule):
            out.append(r)
        elif isinstance(r, str):
            out.append(engine.ScalingRule.named(r))
        else:
            out.append(engine.ScalingRule(**r))
    return out


def _seeds(data: dict, fields: dict) -> tuple[list, list]:
    """(reference seeds, coarse seeds) as ``engine.StudySpec`` fills them in."""
    seeds = data.get("seeds") or None
    ref_seeds = data.get("reference_seeds") or seeds or [fields.get("seed", 1)]
    return list(ref_seeds), list(seeds or ref_seeds)


def _decide_caps(data: dict) -> tuple[int, int] | None:
    """(most reference seeds, most seeds per variant) of a study that adds seeds until
    decided (``decide``), else None; the engine's defaults where the body leaves them."""
    if not data.get("decide"):
        return None
    info = {i.name: i for i in engine.core.records.describe(engine.StudySpec)}
    return (
        int(data.get("max_reference_seeds") or info["max_reference_seeds"].default),
        int(data.get("max_seeds") or info["max_seeds"].default),
    )


def plan_counts(data: dict) -> int:
    """Runs of the study (reference seeds + seeds x radii x rules, + seeds x radii resolution
    controls), from the raw fields; with ``decide`` the most it may run (every variant and
    the reference at its seed cap; controls take no added seeds)."""
    fields = reference_fields(data)
    ref_seeds, seeds = _seeds(data, fields)
    radii = data.get("coarse_radii") or [5e-3]
    n_rules = len(data["rules"]) if data.get("rules") is not None else len(_rules(data))
    n_controls = len(seeds) * len(radii) if data.get("controls", True) else 0
    caps = _decide_caps(data)
    if caps is not None:
        return (
            max(caps[0], len(ref_seeds))
            + max(caps[1], len(seeds)) * len(radii) * n_rules
            + n_controls
        )
    return len(ref_seeds) + len(seeds) * len(radii) * n_rules + n_controls


def worst_stage_times(test: engine.UniaxialTest) -> dict[str, float]:
    """The longest simulated time [s] each stage of ``test`` can run before the engine ends
    it (by its criterion or its bound): ``max_stage_time``, or less where the stage's
    physics ends it sooner. The fill ends only by settling: ``max_stage_time``. The platen
    of pre-compression and consolidation cannot travel further than the pour column
    (the stress would rise without bound first); unloading cannot take longer than that
    travel back; a hold ends only by coming to rest; the release ends at ``release_time``
    (or a few particle fall times); unconfined compression at ``max_unconfined_strain`` of a
    sample at most the pour column tall."""
    cap = test.max_stage_time
    travel = test.pour_height / test.platen_speed
    out = {
        "fill": cap,
        "pre_compression": min(cap, travel),
        "consolidation": min(cap, travel),
        "unloading": min(cap, travel),
    }
    if test.hold_time is not None:  # ends by coming to rest: max_stage_time
        out["hold"] = cap
    if test.unconfined:
        t_min = 5 * math.sqrt(2 * test.radius / test.gravity)
        out["release"] = min(cap, max(t_min, test.release_time))
        out["unconfined"] = min(cap, test.max_unconfined_strain * travel)
    return out


@dataclass(frozen=True)
class RunCost:
    """The worst case of one planned run: its key, particles, steps and curve samples."""

    key: str
    particles: float
    steps: float
    samples: float

    @property
    def particle_steps(self) -> float:
        return self.particles * self.steps


def run_cost(key: str, test: engine.UniaxialTest, dt: float) -> RunCost:
    """The worst case of ``test`` run with time step ``dt`` [s]: every stage at its
    :func:`worst_stage_times`, a curve sample every ``output_interval`` (at least a step)
    and one more at each stage's start."""
    times = worst_stage_times(test)
    stage_steps = [max(1.0, _ceil(t / dt)) for t in times.values()]
    ratio = test.output_interval / dt
    sample_steps = max(1.0, float(round(ratio)) if math.isfinite(ratio) else math.inf)
    samples = sum(
        1 + _ceil(n / sample_steps) if math.isfinite(sample_steps) else 1.0 for n in stage_steps
    )
    return RunCost(key, float(test.n_particles), float(sum(stage_steps)), float(samples))


def _ceil(x: float) -> float:
    """``math.ceil`` that keeps an infinity (a time step of 5e-324 s: inf steps, refused by
    the caps, not an OverflowError)."""
    return float(math.ceil(x)) if math.isfinite(x) else math.inf


def reference_dt(fields: dict) -> float:
    """The reference's time step [s]: ``dt``, or the one its run takes (``dt_fraction`` of
    the critical time of its stiffest contact, :meth:`engine.UniaxialTest.resolved_dt`)."""
    dt = fields.get("dt")
    return float(dt) if dt is not None else float(probe(fields).resolved_dt())


def worst_case(data: dict) -> list[RunCost]:
    """:class:`RunCost` of every planned run, in plan order, from the raw fields (as
    ``engine.plan`` would plan them, nothing built)."""
    fields = reference_fields(data)
    ref_seeds, seeds = _seeds(data, fields)
    radii = data.get("coarse_radii") or [5e-3]
    rules = _rules(data)
    dt_ref = reference_dt(fields)
    ref = probe(fields)
    out = [run_cost(f"ref-s{s}", ref, dt_ref) for s in ref_seeds]
    coarse = {}
    for r in radii:
        test = probe(fields, radius=r)
        for rule in rules:
            dt = dt_ref * (r / ref.radius if rule.dt == "scaled" else 1.0)
            coarse[r, rule.name] = run_cost(f"r{r * 1e3:g}mm-{rule.name}", test, dt)
    controls = {}
    if data.get("controls", True):
        for r in radii:  # engine.study.plan.control_test: the reference's cell scaled by s
            s = ref.radius / r
            test = probe(
                fields,
                cell=tuple(c * s for c in ref.cell),
                platen_speed=ref.platen_speed * s,
                gravity=ref.gravity / s,
            )
            controls[r] = run_cost(f"ctl-r{r * 1e3:g}mm", test, dt_ref)
    for s in seeds:
        for r in radii:
            for rule in rules:
                c = coarse[r, rule.name]
                out.append(dataclasses.replace(c, key=f"{c.key}-s{s}"))
            if r in controls:
                out.append(dataclasses.replace(controls[r], key=f"{controls[r].key}-s{s}"))
    caps = _decide_caps(data)
    if caps is not None:
        extra = [out[0]] * max(0, caps[0] - len(ref_seeds)) + [
            c for c in coarse.values() for _ in range(max(0, caps[1] - len(seeds)))
        ]
        if extra:
            out.append(_added_worst_case(extra, ref, coarse, radii, rules, dt_ref, data, fields))
    return out


def _added_worst_case(
    extra: list[RunCost], ref, coarse, radii, rules, dt_ref, data, fields
) -> RunCost:
    """One :class:`RunCost` for every run a ``decide`` study may add: all of them at their
    seed caps, or, with a ``budget`` of (estimated) particle-steps, that budget times the
    largest ratio of worst-case to estimated particle-steps (and of curve samples to
    estimated particle-steps) of the runs they copy, whichever is less."""
    from engine.study.plan import estimated_steps

    particle_steps = sum(c.particle_steps for c in extra)
    samples = sum(c.samples for c in extra)
    budget = data.get("budget")
    if budget is not None:
        typical = {"ref": estimated_steps(ref) * ref.n_particles}
        for r in radii:
            test = probe(fields, radius=r)
            for rule in rules:
                dt = dt_ref * (r / ref.radius if rule.dt == "scaled" else 1.0)
                typical[r, rule.name] = estimated_steps(dataclasses.replace(test, dt=dt)) * (
                    test.n_particles
                )
        pairs = [(out_c, typical["ref"]) for out_c in extra[:1] if out_c.key.startswith("ref")]
        pairs += [(coarse[k], typical[k]) for k in coarse]
        ps_ratio = max(c.particle_steps / t for c, t in pairs if t > 0)
        sample_ratio = max(c.samples / t for c, t in pairs if t > 0)
        particle_steps = min(particle_steps, ps_ratio * float(budget))
        samples = min(samples, sample_ratio * float(budget))
    particles = max(c.particles for c in extra)
    return RunCost(
        "runs added until decided (worst case)", particles, particle_steps / particles, samples
    )


def work_bounds(fields: dict, dt: float) -> list[tuple[str, float, str]]:
    """The knobs of the reference ``fields`` (time step ``dt`` [s]) outside
    :data:`BOUNDS`: (field, value, the bound in words) for each."""
    test = probe(fields)
    out = []
    oi = fields["output_interval"]
    top = SAMPLE_STRAIN * test.cell[2] / test.platen_speed
    if oi < dt:
        out.append(
            ("output_interval", oi, f">= dt = {dt:.4g} s (one curve sample a time step at most)")
        )
    elif oi > top * (1 + 1e-9):  # (rounding of the bound itself)
        out.append(
            (
                "output_interval",
                oi,
                f"<= {top:.4g} s ({SAMPLE_STRAIN:g} x H / "
                "platen_speed: one curve sample per 1 % of axial strain at least)",
            )
        )
    fall = 2 * test.fall_time
    scale = max(fall, test.pour_height / test.platen_speed)
    cap = STAGE_TIME_FACTOR * scale
    if fields["max_stage_time"] > cap:
        out.append(
            (
                "max_stage_time",
                fields["max_stage_time"],
                f"<= {cap:.4g} s ({STAGE_TIME_FACTOR:g} x max(2 fall times of the "
                f"pour column = {fall:.3g} s, pour column / platen_speed = "
                f"{test.pour_height / test.platen_speed:.3g} s))",
            )
        )
    if fields["settle_ke"] < MIN_SETTLE_KE:
        out.append(
            (
                "settle_ke",
                fields["settle_ke"],
                f">= {MIN_SETTLE_KE:g} (a fill never "
                "settles below that: it would run to max_stage_time)",
            )
        )
    return out


#: Bytes a curve sample costs on disk at worst: 11 float64 values, in the run's file and
#: again in the study's results.h5.
BYTES_PER_SAMPLE = 2 * 11 * 8
#: Bytes a particle costs per stage at worst: positions and radii at the stage's end (in the
#: run file and results.h5) and its share of the ParaView snapshots (particles, contacts).
BYTES_PER_PARTICLE_STAGE = 512


def output_bytes(costs: list[RunCost]) -> float:
    """What a study's files can take on disk at worst [bytes] (an estimate on the safe side:
    its worst-case curve samples, and the stage-end state of every particle of every run)."""
    return float(
        sum(
            BYTES_PER_SAMPLE * c.samples + 6 * BYTES_PER_PARTICLE_STAGE * c.particles for c in costs
        )
    )


def stored_bytes(directories) -> int:
    """Bytes of the files under ``directories`` (missing ones count 0)."""
    import os

    total = 0
    for d in directories:
        for root, _, files in os.walk(d):
            for f in files:
                try:
                    total += os.stat(os.path.join(root, f)).st_size
                except OSError:  # removed meanwhile
                    pass
    return total
