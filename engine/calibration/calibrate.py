r"""Calibration of a contact law to a powder's laboratory data (docs/CALIBRATION.md).

:func:`calibrate` finds the law parameters whose uniaxial test reproduces
:class:`~engine.calibration.targets.LabTargets`, with a posterior that says which parameters
the data determine and which they leave free. The method, chosen for few runs (each is a
DEM simulation of minutes to hours) and for long-term maintenance (numpy only, as the
engine):

1. **design**: a space-filling (maximin Latin hypercube) set of ``runs`` parameter sets in
   the box ``parameters`` (log scale for a positive range wider than 4x, and for f0 by its
   magnitude), each run (its fill once, then one branch per consolidation stress the targets
   need: :func:`engine.flow_function`) and stored as it finishes;
2. **emulators**: a Gaussian process per measured quantity, in logs, with a noise term for
   the seed-to-seed scatter (:class:`~engine.calibration.gp.GP`);
3. **waves** of ``wave_runs`` runs by history matching (Vernon, Goldstein and Bower 2010):
   the implausibility :math:`I(x) = \max_j |E[y_j(x)] - z_j| / \sqrt{V_j(x) + \sigma_j^2 +
   \nu_j}` (emulator, laboratory and seed variance) rules out parameter sets with
   :math:`I > 3`; the next runs fill what is left, as far from each other as they can be;
4. **posterior** by random-walk Metropolis on the emulators (Kennedy and O'Hagan 2001, the
   emulator variance in the likelihood), uniform prior in the box; a parameter is
   *determined* where its posterior spread is under half its prior spread (in the scaled
   box), else *free*;
5. **sensitivity**: first-order Sobol indices of each quantity's emulator mean over the box
   (Saltelli 2010 estimator): which target moves with which parameter;
6. **check**: the posterior median is run once more, and each target is *met* when the run is
   within two standard deviations (laboratory and seed scatter together); a target not met
   is named with how far off it is.

Two guards for real data (issue 41 item 4): a strength is read only from a sample that
failed at a peak (one that hardened to the strain limit gives no value, and a target most
design runs give no value for is refused, naming it); and where the model at its best is
further from the data than their errors allow, the posterior's variances are widened by the
Birge ratio (:func:`model_discrepancy`), stated in the result.
"""

from __future__ import annotations

import concurrent.futures as cf
import dataclasses
import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..core.errors import ParameterError
from ..core.records import describe
from ..io.store import load_run, save_run
from ..study.channel import wait_tasks
from ..uniaxial.flow import flow_function
from ..uniaxial.spec import UniaxialTest
from .forward import (
    SHEAR,
    SHEAR_UNITS,
    Forward,
    cell_summary,
    check_shear_cell,
    measure_shear,
    run_shear_tests,
    shear_curves,
    shear_tests,
    store_loci,
    stored_loci,
)
from .gp import GP
from .targets import LabTargets

#: Law parameters a calibration may set.
CALIBRATED = ("k1", "k2", "f0", "kadh", "mu_s", "mu_r", "n", "chi", "restitution")
#: Implausibility above which a parameter set is ruled out.
IMPLAUSIBLE = 3.0
#: Posterior spread / prior spread (scaled box) under which a parameter is determined.
DETERMINED = 0.5
#: Largest adhesive-branch stiffness a box may reach, as a multiple of the unloading
#: stiffness K2 [-] (:func:`check_kadh_box`): a contact unloaded from dmax leaves the K2
#: branch for the adhesive branch f0 - kadh d^chi where they meet, and its pull-off force,
#: |f0| + kadh K2 / (K2 + kadh) dp^n (chi = n), saturates at |f0| + K2 dp^n as kadh grows,
#: within 1 / (1 + kadh / K2) of it: above 10 K2 no force of the law moves by more than 9 %.
KADH_MAX_RATIO = 10.0


@dataclass(frozen=True)
class _Axis:
    name: str
    lo: float
    hi: float

    @property
    def log(self) -> bool:
        a, b = abs(self.lo), abs(self.hi)
        return self.lo * self.hi > 0 and max(a, b) / min(a, b) >= 4.0

    def value(self, u: float) -> float:
        if self.log:
            sign = 1.0 if self.lo > 0 else -1.0
            a, b = math.log(abs(self.lo)), math.log(abs(self.hi))
            return sign * math.exp(a + u * (b - a))
        return self.lo + u * (self.hi - self.lo)


def _number_pair(field: str, value, limit: str) -> tuple[float, float]:
    """``value`` as two floats (in its own unit); anything else: ParameterError at
    ``field`` with ``limit``."""
    try:
        a, b = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ParameterError(field, value, limit) from None
    return a, b


def _axes(base_law, parameters: dict) -> list[_Axis]:
    if not parameters:
        raise ParameterError("calibrate.parameters", parameters, "at least one law parameter")
    out = []
    fields = {f.name for f in dataclasses.fields(base_law)}
    for name, box in parameters.items():
        if name not in CALIBRATED or name not in fields:
            have = [p for p in CALIBRATED if p in fields]
            raise ParameterError(f"calibrate.parameters.{name}", name, f"one of {have}")
        lo, hi = _number_pair(f"calibrate.parameters.{name}", box, "a (low, high) pair of numbers")
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise ParameterError(f"calibrate.parameters.{name}", box, "finite, low < high")
        out.append(_Axis(name, lo, hi))
    return out


def _law(base_law, axes: list[_Axis], u: np.ndarray):
    return replace(base_law, **{a.name: a.value(float(x)) for a, x in zip(axes, u)})


def _test(
    base_test: UniaxialTest,
    axes: list[_Axis],
    u,
    shear: tuple = (),
    uniaxial: bool = True,
    seed_offset: int = 0,
) -> UniaxialTest | Forward | str:
    """The test of parameter set ``u``, or the reason it cannot be made (a law the test
    refuses, e.g. too soft to carry the consolidation stress within the overlap limit: left
    out like a run that failed, at no cost). With shear targets (``shear``: the base shear
    tests, one per locus) a :class:`~engine.calibration.forward.Forward` of the uniaxial
    test (where ``uniaxial``) and the shear tests with the parameter set's law; each test's
    packing seed moved by ``seed_offset`` (``calibrate(..., vary_seed=True)``)."""
    try:
        law = _law(base_test.pair_law, axes, u)
        return _forward(base_test, law, shear, uniaxial, seed_offset)
    except ParameterError as e:
        return f"ParameterError: {e}"


def _forward(base_test: UniaxialTest, law, shear: tuple, uniaxial: bool, seed_offset: int = 0):
    """The tests of ``law``: the base test with it (no shear targets), else a
    :class:`Forward` of it (where ``uniaxial``: shear data alone never build the uniaxial
    test, whose consolidation a law may be refused for) and each base shear test with it;
    each with its packing seed moved by ``seed_offset`` (0: the base tests' own)."""
    if not shear:
        return replace(base_test, pair_law=law, seed=base_test.seed + seed_offset)
    test = replace(base_test, pair_law=law, seed=base_test.seed + seed_offset) if uniaxial else None
    return Forward(test, tuple(replace(t, pair_law=law, seed=t.seed + seed_offset) for t in shear))


def _feasible(base_law, axes, u) -> bool:
    try:
        _law(base_law, axes, u)
    except (ParameterError, ValueError):
        return False
    return True


def _maximin(rng, n: int, d: int, ok, tries: int = 40) -> np.ndarray:
    """A maximin Latin hypercube of ``n`` feasible points in [0, 1]^d: of ``tries`` Latin
    hypercubes (``scipy.stats.qmc.LatinHypercube``), the one whose closest two points are
    farthest apart (the maximin criterion, which scipy's optimisers of a hypercube do not
    offer); infeasible points of a hypercube are drawn again uniformly until ``ok``."""
    from scipy.stats import qmc

    best, score = None, -1.0
    for _ in range(tries):
        x = qmc.LatinHypercube(d, seed=rng).random(n)
        for i in range(n):
            k = 0
            while not ok(x[i]) and k < 1000:
                x[i] = rng.random(d)
                k += 1
        dist = np.sqrt(((x[:, None, :] - x[None, :, :]) ** 2).sum(-1)) + np.eye(n) * 9
        s = float(dist.min())
        if s > score:
            best, score = x, s
    return best


# ------------------------------------------------------------------ what a run measures
def branch_stresses(base: UniaxialTest, targets: LabTargets) -> tuple[float, ...]:
    """Consolidation stresses the runs need [Pa]: every strength target's and, for the
    compression curve, stiffness and K0 targets (read on the highest branch), the base
    test's or the highest compression target's where no strength branch reaches it; none
    where the targets are a shear tester's alone (the uniaxial test is not run)."""
    s = {p.consolidation_stress for p in targets.strength}
    if set(targets.uniaxial_names()) - {"strength"}:
        need = max([base.consolidation_stress, *[p.stress for p in targets.compression]])
        if not s or max(s) < need:  # the highest branch is where those are read
            s.add(need)
    return tuple(sorted(s))


#: The unit of each kind of target (a quantity's name up to its "@").
TARGET_UNITS = {
    "porosity": "1",
    "loading_stiffness": "Pa",
    "unloading_stiffness": "Pa",
    "k0": "1",
    "strength": "Pa",
    **SHEAR_UNITS,
}


def _uniaxial(results: dict) -> dict:
    """The uniaxial branches of a run's outcome (consolidation stress -> result)."""
    return {s: r for s, r in results.items() if s != SHEAR}


def compression_branch(result, branch: str, curve: str = "porosity"):
    """(top platen stress [Pa], ``curve`` [-]) of a uniaxial run's ``branch`` ("loading":
    pre-compression and consolidation; "unloading") as a compression target is read: the
    stress made monotonic (its running maximum, unloading read backwards) and the first
    sample at each stress kept, so that ``np.interp`` reads the curve at a stress. On
    loading, the samples before the platen carries any stress are left out: their
    "porosity" counts the gap above the bed, and a target below the first loaded stress
    would be read between it and the bed's."""
    if branch == "loading":
        parts = [result.stages[s].curves for s in ("pre_compression", "consolidation")]
        sig = np.concatenate([c["stress_top"] for c in parts])
        por = np.concatenate([c[curve] for c in parts])
        loaded = np.flatnonzero(sig > 0)
        if loaded.size:
            sig, por = sig[loaded[0] :], por[loaded[0] :]
    else:
        c = result.stages["unloading"].curves
        sig, por = c["stress_top"][::-1], c[curve][::-1]
    sig = np.maximum.accumulate(sig)
    _, idx = np.unique(sig, return_index=True)
    return sig[idx], por[idx]


def measure(results: dict, base: UniaxialTest, targets: LabTargets) -> list[dict]:
    """Each target quantity of ``targets`` read from a run's ``results`` (consolidation
    stress -> :class:`engine.UniaxialResult`, and under ``"shear"`` the shear tests'
    results: :func:`engine.calibration.forward.measure_shear`): name, lab value, lab sd and
    the run's value. The compression curve, the stiffnesses and K0 are read from the branch
    at the highest consolidation stress (a tester's one consolidation), each strength from
    its own."""
    out = []
    if targets.shear:
        shear = measure_shear(results[SHEAR], targets)
    results = _uniaxial(results)
    if not targets.uniaxial_names():
        return shear
    top = results[max(results)]
    for p in targets.compression:
        sig, por = compression_branch(top, p.branch)
        value = float(np.interp(p.stress, sig, por))
        out.append(
            {
                "name": f"porosity@{p.stress:g}Pa:{p.branch}",
                "lab": p.porosity,
                "sd": p.sd,
                "value": value,
                "unit": "1",
            }
        )
    for name in ("loading_stiffness", "unloading_stiffness", "k0"):
        lab = getattr(targets, name)
        if lab is not None:
            out.append(
                {
                    "name": name,
                    "lab": lab,
                    "sd": getattr(targets, f"{name}_sd"),
                    "value": float(top.scalars[name]),
                    "unit": TARGET_UNITS[name],
                }
            )
    for p in targets.strength:
        r = results[p.consolidation_stress]
        # a strength is the peak of a sample that failed; one that hardened to the strain
        # limit has a stress there, not a strength (docs/FAILURE.md): no value
        peaked = bool(r.scalars.get("unconfined_failure", 1.0))
        row = {
            "name": f"strength@{p.consolidation_stress:g}Pa",
            "lab": p.strength,
            "sd": p.sd,
            "value": float(r.scalars["unconfined_strength"]) if peaked else math.nan,
            "unit": "Pa",
        }
        if not peaked:
            row["no_peak"] = True
        out.append(row)
    return out + shear if targets.shear else out


#: The resolution-curve property (engine.study.resolution) that corrects each kind of target
#: (a target's name up to its "@"); K0 has none.
CORRECTED_BY = {
    "porosity": "density",
    "loading_stiffness": "loading_stiffness",
    "unloading_stiffness": "unloading_stiffness",
    "strength": "strength",
}


def resolution_corrections(curve: dict) -> dict[str, tuple[float, float]]:
    """Corrections for a calibration run in a study's reference cell, from that study's
    resolution curve (``StudyResult.report.resolution_curve.to_dict()``, or its summary's
    ``advisor["resolution_curve"]``): per
    kind of target, the factor bulk / cell value, 1 / (1 + the reference's offset from the
    bulk), and the standard deviation of its logarithm (from the offset's interval and its
    degrees of freedom). Only properties the curve has are corrected."""
    from ..study.intervals import t_quantile

    conf = float(curve.get("confidence", 0.95))
    out = {}
    for kind, metric in CORRECTED_BY.items():
        c = curve.get("metrics", {}).get(metric)
        if c is None:
            continue
        lo, hi = c["reference_offset_interval"]
        df = c.get("reference_offset_df", math.inf)
        q = t_quantile(0.5 + conf / 2, df) if math.isfinite(df) else 1.959963984540054
        sd = (math.log1p(hi) - math.log1p(lo)) / (2 * q) if q > 0 else math.inf
        out[kind] = (1.0 / (1.0 + c["reference_offset"]), sd)
    return out


def check_corrections(resolution: dict | None) -> dict:
    """``resolution`` of :func:`calibrate` checked: kind -> (factor > 0, sd >= 0); raises
    :class:`engine.ParameterError` naming the kind."""
    if resolution is None:
        return {}
    out = {}
    for kind, pair in resolution.items():
        if kind not in CORRECTED_BY:
            raise ParameterError(
                f"calibrate.resolution.{kind}", kind, f"one of {list(CORRECTED_BY)}"
            )
        factor, sd = _number_pair(
            f"calibrate.resolution.{kind}", pair, "a (factor, sd of its log) pair"
        )
        if not (math.isfinite(factor) and factor > 0 and math.isfinite(sd) and sd >= 0):
            raise ParameterError(
                f"calibrate.resolution.{kind}", pair, "factor > 0, 0 <= sd of its log < inf"
            )
        out[kind] = (factor, sd)
    return out


def _corrected(quantities: list[dict], corrections: dict) -> list[dict]:
    """``quantities`` as bulk values: each target of a corrected kind has its cell's value
    (``cell_value``) times the factor (porosity through the solid fraction, 1 - n), and the
    correction's relative sd (``correction_sd``), which adds to the laboratory's."""
    if not corrections:
        return quantities
    out = []
    for q in quantities:
        kind = q["name"].split("@")[0]
        if kind not in corrections or not math.isfinite(q["value"]):
            out.append(q)
            continue
        factor, sd = corrections[kind]
        v = q["value"]
        if kind == "porosity":  # the density (1 - n) is what the curve corrects
            bulk = 1.0 - (1.0 - v) * factor
            rel = sd * (1.0 - bulk) / bulk if bulk > 0 else math.inf
        else:
            bulk, rel = v * factor, sd
        out.append({**q, "value": bulk, "cell_value": v, "correction_sd": rel})
    return out


def _run_point(
    test: UniaxialTest | Forward,
    stresses: tuple[float, ...],
    key: str = "",
    channel=None,
    limit: tuple | None = None,
    backend: str | None = None,
    threads: int | None = None,
    progress=None,
) -> dict | str:
    """One parameter set: its fill once, one branch per consolidation stress (a picklable
    task for an executor); the error text where the run stops (a stage that misses its
    criterion, an instability, the wall-time limit): such a parameter set is left out, not
    the calibration. ``progress`` (in this process) or ``channel`` (a task elsewhere:
    :class:`engine.FileChannel`) hears the run and may stop it
    (:class:`engine.StopRequested`, not caught); ``limit``: (max_wall_time [s], the
    setting's name); ``threads``: engine threads of a task. A :class:`Forward` runs its
    uniaxial test (if any) and then its shear tests (:func:`engine.run_shear`, on the CPU
    whatever ``backend``; the wall-time limit checked at each curve sample), their results
    under ``"shear"``; a shear test that misses a stage's criterion, blows up or gives a
    non-finite curve (FloatingPointError) leaves the parameter set out, as a failed uniaxial
    run does."""
    from ..core.errors import InstabilityError, StopRequested, WallTimeExceeded
    from ..study.channel import task_progress
    from ..uniaxial.driver import StageError, run_uniaxial

    if threads is not None:
        import numba

        numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
    if channel is not None:
        if channel.stop_requested():
            raise StopRequested(f"calibration run {key} not started: the calibration was stopped")
        progress = task_progress(channel, key)
    how = {"progress": progress, "backend": backend}
    if limit is not None and limit[0] is not None:
        how.update(max_wall_time=limit[0], wall_time_setting=limit[1])

    def uniaxial(test: UniaxialTest, how: dict) -> dict:
        if test.unconfined:
            ff = flow_function(test, stresses, **how)
            return dict(zip(ff.consolidation_stresses, ff.results))
        return {stresses[-1]: run_uniaxial(replace(test, consolidation_stress=stresses[-1]), **how)}

    try:
        if not isinstance(test, Forward):
            return uniaxial(test, how)
        parts = int(test.uniaxial is not None) + int(bool(test.shear))
        out = {}
        if test.uniaxial is not None:
            out.update(uniaxial(test.uniaxial, {**how, "progress": _share(progress, 0, parts)}))
        if test.shear:
            heard = _wall_limited(_share(progress, parts - 1, parts), limit)
            out[SHEAR] = run_shear_tests(test.shear, heard)
        return out
    except (StageError, InstabilityError, WallTimeExceeded) as e:
        return f"{type(e).__name__}: {e}"
    except FloatingPointError as e:  # a shear test's non-finite curve (docs/SHEAR.md)
        if not isinstance(test, Forward):
            raise
        return f"{type(e).__name__}: {e}"
    except ParameterError as e:
        # a fill this run's packing seed cannot place without overlap (with vary_seed each
        # run packs its own seed): left out like a failed run; any other refusal is the
        # request's, checked before anything runs
        if e.field != "UniaxialTest.pour_fraction":
            raise
        return f"{type(e).__name__}: {e}"


def _share(progress, i: int, n: int):
    """``progress`` hearing part ``i`` of ``n`` of a run as that share of the whole."""
    if progress is None or n <= 1:
        return progress
    return lambda p: progress(replace(p, fraction=(i + p.fraction) / n))


def _wall_limited(progress, limit: tuple | None):
    """``progress`` that also stops the run with :class:`engine.WallTimeExceeded` once it
    has run longer than ``limit`` = (seconds, the setting's name) from now (checked at each
    curve sample: :func:`engine.run_shear` takes no limit of its own)."""
    import time

    from ..core.errors import WallTimeExceeded

    if limit is None or limit[0] is None:
        return progress
    start = time.monotonic()

    def heard(p):
        elapsed = time.monotonic() - start
        if elapsed > limit[0]:
            raise WallTimeExceeded(limit[0], elapsed, limit[1])
        return None if progress is None else progress(p)

    return heard


def _curves(results: dict | str) -> dict:
    """The check run's curves as the page and the API show them: porosity against the top
    platen's stress on loading (pre-compression and consolidation) and unloading of the
    highest branch [Pa, -], the flow function (one row per branch) and, with shear targets,
    the yield loci (:func:`engine.calibration.forward.shear_curves`)."""
    if isinstance(results, str):
        return {}
    out = {}
    if SHEAR in results:
        out["yield_loci"] = shear_curves(results[SHEAR])
    results = _uniaxial(results)
    if not results:
        return out
    top = results[max(results)]
    for part, stages in (
        ("loading", ("pre_compression", "consolidation")),
        ("unloading", ("unloading",)),
    ):
        curves = [top.stages[s].curves for s in stages if s in top.stages]
        if curves:
            out[part] = {
                "stress": np.concatenate([c["stress_top"] for c in curves]).tolist(),
                "porosity": np.concatenate([c["porosity"] for c in curves]).tolist(),
            }
    if "unconfined_strength" in top.scalars:
        out["flow_function"] = [
            {
                "consolidation_stress": float(s),
                "strength": float(r.scalars["unconfined_strength"]),
                "ffc": float(s / r.scalars["unconfined_strength"])
                if r.scalars["unconfined_strength"] > 0
                else None,
            }
            for s, r in sorted(results.items())
        ]
    return out


# ------------------------------------------------------------------ the result
@dataclass
class Calibration:
    """What :func:`calibrate` gives back (module docstring).

    Attributes: ``law`` (the posterior median's law), ``parameters`` (per parameter: median,
    90 % credible interval, ``determined`` or ``free``, its posterior / prior spread),
    ``targets_met`` (per target quantity: lab value and sd, the check run's value, its z and
    whether it is met), ``sensitivity`` (per quantity, each parameter's first-order Sobol
    index), ``runs`` (every run's parameters and measured quantities, by wave),
    ``not_met`` (the targets missed, in words), ``curves`` (the check run's compression
    curve and flow function: :func:`_curves`), ``resolution`` (the corrections applied: kind
    -> (factor, sd of its log); the quantities then carry ``cell_value``), ``posterior``
    (:func:`_posterior`: samples in the law's units and the parameters' correlation, which
    shows pairs the data determine only together), ``test`` (the calibrated test: the base
    test with :attr:`law`), ``shear_test`` (the shear cell of shear targets: a shear test's
    fields but the law and stresses, JSON; None without), ``discrepancy`` (the model's
    distance from the data at its best and the inflation applied:
    :func:`model_discrepancy`)."""

    law: object
    parameters: dict
    targets_met: list[dict]
    sensitivity: dict
    runs: list[dict]
    not_met: list[str] = field(default_factory=list)
    curves: dict = field(default_factory=dict)
    resolution: dict = field(default_factory=dict)
    posterior: dict = field(default_factory=dict)
    test: UniaxialTest | None = None
    shear_test: dict | None = None
    discrepancy: dict | None = None

    @property
    def all_met(self) -> bool:
        """Whether the check run met every target (a calibration that did not is a result
        too, but not a law to use as it is: :attr:`not_met` says which and by how much)."""
        return not self.not_met

    def study(self, spec=None):
        """The scaling study of the calibrated law, to hand to :func:`engine.run_study`:
        ``spec``'s radii, rules and seeds (an :class:`engine.StudySpec`; None: the default
        study's) with the calibrated test as its reference. Calibrate, then coarsen:
        ``engine.run_study(cal.study())``; its report names the coarsest radius each rule
        keeps every property within tolerance at, and the law to run there."""
        from ..study.spec import default_study

        return replace(spec if spec is not None else default_study(), reference=self.test)

    def to_summary(self) -> dict:
        """JSON-friendly form; ``determination``: :func:`determination` of it (whether the
        data determine the parameters, and which target would determine a free one)."""
        from ..core.records import to_dict

        out = {
            "law": {"type": type(self.law).__name__, **to_dict(self.law)},
            # the particle radius the law is calibrated for [m]: scaling it elsewhere needs it
            "reference_radius": self.test.radius
            if self.test is not None
            else (None if self.shear_test is None else self.shear_test["radius"]),
            "all_targets_met": self.all_met,
            "parameters": self.parameters,
            "targets_met": self.targets_met,
            "sensitivity": self.sensitivity,
            "runs": self.runs,
            "not_met": self.not_met,
            "curves": self.curves,
            "resolution": {k: list(v) for k, v in self.resolution.items()},
            "posterior": self.posterior,
            "shear_test": self.shear_test,
            "discrepancy": self.discrepancy,
        }
        out["determination"] = determination(out)
        return out


#: First-order Sobol index under which no target of a calibration is said to move a
#: parameter (a tighter measurement of that target would not determine it).
MOVES = 0.2


def determination(summary: dict) -> dict:
    """Whether the data determine the calibration's parameters, in words to say first, and
    for each free parameter which target would determine it (from the Sobol indices: the
    target whose variance over the box that parameter explains most).

    ``summary``: :meth:`Calibration.to_summary` (or a stored ``calibration.json``). Returns
    ``{"all_free": bool, "free": [names], "lines": [...], "parameters": {name: {"status",
    "target", "sobol", "lab_sd"}}}``: ``target`` None where no target's index reaches
    :data:`MOVES` (no target here moves it: one that does must be added), ``lab_sd`` the
    target's laboratory sd relative to its value. A calibration whose parameters are all
    free meets its targets with any law of the box: its first line says so."""
    params = summary.get("parameters") or {}
    sens = summary.get("sensitivity") or {}
    labs = {q["name"]: q for q in summary.get("targets_met") or []}
    free = [n for n, p in params.items() if p.get("status") == "free"]
    out: dict = {}
    for name, p in params.items():
        ranked = sorted(
            ((row.get(name, 0.0), target) for target, row in sens.items()), reverse=True
        )
        index, target = ranked[0] if ranked else (0.0, None)
        lab = labs.get(target) or {}
        rel = abs(lab["sd"] / lab["lab"]) if lab.get("lab") and lab.get("sd") is not None else None
        out[name] = {
            "status": p.get("status"),
            "target": target if index >= MOVES else None,
            "sobol": float(index),
            "lab_sd": rel,
        }
    lines = []
    if params and len(free) == len(params):
        names = ", ".join(free)
        lines.append(
            f"The data determine none of the parameters: {names} "
            f"{'is' if len(free) == 1 else 'are all'} free (each 90 % interval spans most of "
            "its box), so a target met here says only that some law in the box meets it, "
            "not which law."
        )
    elif free:
        lines.append(
            f"The data leave {', '.join(free)} free (the 90 % interval spans most of the "
            "box); the other parameters are determined."
        )
    for name in free:
        d = out[name]
        if d["target"] is None:
            best = f" (the largest Sobol index, {d['sobol']:.2f})" if sens else ""
            lines.append(
                f"{name}: no target of this calibration moves it{best}: a target that "
                f"depends on {name} must be added to determine it."
            )
            continue
        sd = "" if d["lab_sd"] is None else f" (now +/- {100 * d['lab_sd']:.3g} %)"
        lines.append(
            f"{name}: {d['target']} moves it most (Sobol index {d['sobol']:.2f}): a tighter "
            f"measurement of {d['target']}{sd} would determine it."
        )
    return {
        "all_free": bool(params) and len(free) == len(params),
        "free": free,
        "lines": lines,
        "parameters": out,
    }


def _emulators(u: np.ndarray, ys: np.ndarray) -> list[GP]:
    """One GP per quantity, each on the runs that gave it a value (a strength only from
    samples that failed at a peak: :func:`measure`)."""
    out = []
    for j in range(ys.shape[1]):
        ok = np.isfinite(ys[:, j])
        out.append(GP(u[ok], ys[ok, j], seed=j))
    return out


def _short_quantities(quantities: list[dict], ys: np.ndarray, d: int) -> list[str]:
    """Quantities too few runs gave a value to emulate (fewer than d + 2: a strength where
    most samples hardened instead of failing), in words."""
    short = []
    for j, q in enumerate(quantities):
        n = int(np.isfinite(ys[:, j]).sum())
        if n < d + 2:
            short.append(
                f"{q['name']}: {n} of {len(ys)} runs gave a value (a strength only from a "
                "sample that failed at a peak; docs/FAILURE.md)"
            )
    return short


def _predict(gps: list[GP], u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    mus, vs = zip(*(g.predict(u) for g in gps))
    noise = np.array([g.noise for g in gps])
    return np.column_stack(mus), np.column_stack(vs), noise


def _log_lab(quantities: list[dict]) -> tuple[np.ndarray, np.ndarray]:
    """Lab values and variances in logs (relative sd: sd / value; a 1 % floor), with a
    resolution correction's relative sd added."""
    z = np.array([math.log(q["lab"]) for q in quantities])
    rel = np.array([max(q["sd"] / q["lab"], 0.01) for q in quantities])
    corr = np.array([q.get("correction_sd", 0.0) for q in quantities])
    return z, rel**2 + corr**2


def _floor_log(values: np.ndarray, lab: np.ndarray) -> np.ndarray:
    return np.log(np.maximum(values, 1e-3 * lab))


def check_request(
    base_test: UniaxialTest,
    targets: LabTargets,
    parameters: dict,
    runs: int,
    shear_test=None,
) -> tuple[float, ...]:
    """Check a calibration request without running anything; returns the consolidation
    stresses its runs branch at [Pa] (none where the targets are a shear tester's alone).
    Raises :class:`engine.ParameterError` naming the field: targets that are not a
    :class:`LabTargets`, a parameter the law has not or a bad box, too few design runs,
    strength targets from a test without the unconfined stage, a consolidation stress at or
    below the test's ``pre_stress``; with shear targets, a ``shear_test`` of another particle
    radius, a locus the shear test cannot be set up for with the base law
    (``LabTargets.shear[i]...``: :func:`engine.calibration.forward.shear_tests`)."""
    if not isinstance(targets, LabTargets):
        raise ParameterError("calibrate.targets", type(targets).__name__, "an engine LabTargets")
    law = base_test.pair_law
    axes = _axes(law, parameters)
    if runs < len(axes) + 2:
        raise ParameterError("calibrate.runs", runs, f">= {len(axes) + 2} (parameters + 2)")
    infos = {i.name: i for i in describe(type(law))}
    for a in axes:  # each end of a box within the range the law declares for its field
        info = infos[a.name]
        for end in (a.lo, a.hi):
            if (
                (info.gt is not None and not end > info.gt)
                or (info.ge is not None and not end >= info.ge)
                or (info.lt is not None and not end < info.lt)
                or (info.le is not None and not end <= info.le)
            ):
                raise ParameterError(
                    f"calibrate.parameters.{a.name}",
                    [a.lo, a.hi],
                    f"a box {info.limit_text()} (the law's {a.name})",
                )
    u = _box_points(len(axes))
    if not any(_feasible(law, axes, x) for x in u):  # e.g. K2 < K1 everywhere in the box
        raise ParameterError(
            "calibrate.parameters", parameters, "a box holding laws the law accepts (K2 >= K1)"
        )
    _check_box_ends(base_test, axes, u)
    check_kadh_box(base_test, targets, axes)
    if targets.strength and not base_test.unconfined:
        raise ParameterError(
            "UniaxialTest.unconfined", False, "True (strength targets need the unconfined stage)"
        )
    stresses = branch_stresses(base_test, targets)
    for k, p in enumerate(targets.strength):
        if p.consolidation_stress <= base_test.pre_stress:
            raise ParameterError(
                f"LabTargets.strength[{k}].consolidation_stress",
                p.consolidation_stress,
                f"> the test's pre_stress = {base_test.pre_stress:g} Pa",
            )
    if targets.shear:
        shear_tests(check_shear_cell(base_test, shear_test), targets, base_test.pair_law)
    elif shear_test is not None:
        raise ParameterError(
            "calibrate.shear_test", "a shear test", "given with shear targets only (shear)"
        )
    return stresses


def consolidation_overlap(base_test: UniaxialTest, targets: LabTargets, law=None) -> float:
    """The overlap [m] at which ``law``'s (default: the base test's) virgin loading branch
    carries the contact force of the highest stress the targets consolidate to, sigma (2R)^2
    (one contact per particle diameter squared of a plane; sigma [Pa] the highest uniaxial
    branch's or locus's sigma_pre, R the test's radius [m]): the overlap scale at which
    :func:`check_kadh_box` compares kadh d^chi with K2 d^n when chi != n."""
    law = base_test.pair_law if law is None else law
    sigma = max([*branch_stresses(base_test, targets), *(c.sigma_pre for c in targets.shear)])
    return law.load_overlap(sigma * (2.0 * base_test.radius) ** 2, base_test.radius)[0]


def check_kadh_box(base_test: UniaxialTest, targets: LabTargets, axes: list[_Axis]) -> None:
    """A box for kadh, the adhesive branch's stiffness [N/m^chi], may reach at most
    :data:`KADH_MAX_RATIO` times the unloading stiffness K2 (the box's highest K2 where K2 is
    calibrated too): beyond it the pull-off force |f0| + kadh K2 / (K2 + kadh) dp^n of a
    contact unloaded from a plastic overlap dp is within 9 % of its limit |f0| + K2 dp^n,
    so the data cannot tell such laws apart and the posterior would lean on the box's end.
    With chi = n (the bilinear law; an EEPA law with chi = n) kadh and K2 share a unit and
    the bound is 10 K2; with chi != n it is 10 K2 d_c^(n - chi), kadh d^chi against K2 d^n
    at the overlap d_c of the targets' highest stress (:func:`consolidation_overlap`), the
    most permissive over the ends of n's and chi's boxes where they are calibrated. Raises
    :class:`engine.ParameterError` at ``calibrate.parameters.kadh``."""
    box = {a.name: a for a in axes}
    if "kadh" not in box:
        return
    law0 = base_test.pair_law
    k2 = box["k2"].hi if "k2" in box else law0.k2
    fields = {f.name for f in dataclasses.fields(law0)}
    ns = (box["n"].lo, box["n"].hi) if "n" in box else (law0.n,)
    chis = (box["chi"].lo, box["chi"].hi) if "chi" in box else (law0.chi,)
    bound, at = -math.inf, ""
    for n in ns:
        law = replace(law0, n=n) if "n" in fields else law0
        d_c = consolidation_overlap(base_test, targets, law)
        for chi in chis:
            b = KADH_MAX_RATIO * k2 * d_c ** (n - chi)
            if b > bound:
                bound = b
                at = (
                    ""
                    if n == chi
                    else f" at the overlap d_c = {d_c:.3g} m, n = {n:g}, chi = {chi:g}"
                )
    a = box["kadh"]
    if a.hi > bound:
        unit = describe_unit(law0, "kadh")
        raise ParameterError(
            "calibrate.parameters.kadh",
            [a.lo, a.hi],
            f"a box whose high end is at most {bound:.4g} {unit}: {KADH_MAX_RATIO:g} K2 "
            f"(K2 = {k2:g} {describe_unit(law0, 'k2')}){at}",
            "a contact unloaded from a plastic overlap dp pulls off at |f0| + kadh K2 / "
            "(K2 + kadh) dp^n, which saturates at |f0| + K2 dp^n: beyond 10 K2 no force of the "
            "law moves by more than 9 %, the data cannot tell such kadh apart and the "
            "posterior would lean on the box's end",
        )


def _box_points(d: int, n: int = 256) -> np.ndarray:
    """Points that probe the scaled box [0, 1]^d: its corners (at most 2^9) and a scrambled
    Sobol sequence of ``n`` (``scipy.stats.qmc``; seeded, so a request is judged the same way
    every time)."""
    from scipy.stats import qmc

    corners = np.array(np.meshgrid(*[[0.0, 1.0]] * d, indexing="ij")).reshape(d, -1).T
    return np.vstack([corners, qmc.Sobol(d, scramble=True, seed=0).random(n)])


def _law_error(law, axes: list[_Axis], u: np.ndarray) -> ParameterError | None:
    try:
        _law(law, axes, u)
    except ParameterError as e:
        return e
    return None


def _check_box_ends(base_test: UniaxialTest, axes: list[_Axis], points: np.ndarray) -> None:
    """Each end of each box must hold a law the law accepts (with the other parameters
    somewhere in their boxes: a corner or a probe point) and that the test runs at its time
    step: a box that reaches a law the test's ``dt`` cannot integrate would spend its runs
    failing. The time step is tried one parameter at a time, from the softest law of the box
    the test runs to that end, so that the parameter named is the one that breaks it.
    Raises :class:`engine.ParameterError` naming ``calibrate.parameters.<name>``."""
    law0 = base_test.pair_law
    for i, a in enumerate(axes):
        for end in (0.0, 1.0):
            at_end = points[points[:, i] == end]
            if not any(_feasible(law0, axes, x) for x in at_end):
                why = _law_error(law0, axes, at_end[0])
                raise ParameterError(
                    f"calibrate.parameters.{a.name}",
                    [a.lo, a.hi],
                    f"a box whose {'high' if end else 'low'} end {a.value(end):g} some law "
                    f"accepts with the other parameters in their boxes (the law's "
                    f"{a.name}: {describe_limit(law0, a.name)})",
                    f"{why}" if why is not None else "",
                )
    if base_test.dt is None:  # each run takes its own law's recommended step
        return

    def runs(x) -> ParameterError | None:
        try:
            replace(base_test, pair_law=_law(law0, axes, x))
        except ParameterError as e:
            return e if e.field.endswith(".dt") else None
        return None

    feasible = [x for x in points if _feasible(law0, axes, x)]
    # the softest laws first (stiffness, adhesion and friction grow with u on every axis
    # but f0, whose magnitude does too)
    feasible.sort(key=lambda x: float(np.sum(x)))
    base = next((x for x in feasible if runs(x) is None), None)
    if base is None:
        e = runs(feasible[0])
        raise ParameterError(
            "calibrate.parameters",
            {a.name: [a.lo, a.hi] for a in axes},
            f"a box holding laws the test's time step dt = {base_test.dt:g} s can run",
            f"{e}; lower the boxes' stiff ends, or give the test a smaller dt",
        )
    for i, a in enumerate(axes):
        for end in (0.0, 1.0):
            x = base.copy()
            x[i] = end
            if not _feasible(law0, axes, x):  # the nearest law at this end the law accepts
                at_end = [p for p in feasible if p[i] == end]
                x = min(at_end, key=lambda p: float(np.sum((p - base) ** 2)))
            e = runs(x)
            if e is not None:
                raise ParameterError(
                    f"calibrate.parameters.{a.name}",
                    [a.lo, a.hi],
                    f"a box whose laws the test's time step dt = {base_test.dt:g} s can run",
                    f"at {a.name} = {a.value(end):g} {describe_unit(law0, a.name)}: {e}; "
                    f"lower the box's {'high' if end else 'low'} end, or give the test a "
                    "smaller dt (or dt null: each run takes its law's recommended step)",
                )


def describe_limit(law, name: str) -> str:
    """The declared range of the law's field ``name``, in words, and its cross-field rule."""
    info = next(i for i in describe(type(law)) if i.name == name)
    extra = {"k1": ", <= k2", "k2": ", >= k1"}.get(name, "")
    return f"{info.limit_text()}{extra}"


def describe_unit(law, name: str) -> str:
    """The unit of the law's field ``name``."""
    return next(i.unit for i in describe(type(law)) if i.name == name)


def calibration_runs(runs: int, waves: int, wave_runs: int) -> int:
    """The most parameter sets a calibration runs: its design, its waves and the check run
    (a wave may run fewer where few parameter sets are left)."""
    return runs + waves * wave_runs + 1


def calibrate(
    base_test: UniaxialTest,
    targets: LabTargets,
    parameters: dict,
    *,
    runs: int = 25,
    waves: int = 2,
    wave_runs: int = 15,
    store: str | Path | None = None,
    executor: cf.Executor | None = None,
    seed: int = 0,
    on_run=None,
    progress=None,
    options=None,
    resolution: dict | None = None,
    shear_test=None,
    vary_seed: bool = False,
    discrepancy: bool = True,
) -> Calibration:
    """Calibrate ``base_test``'s pair law to ``targets`` over ``parameters`` ({name: (low,
    high)} in the law's units) with ``runs`` design runs and ``waves`` waves of ``wave_runs``
    (module docstring).

    Args:
        store: a folder where every run (and the check run) is stored as it finishes and
            found again on a rerun (resumable; a run in flight starts again).
        executor: runs a wave's runs as tasks (shorthand for ``options.executor``).
        on_run: ``on_run(index, quantities)`` hears of each finished run, ``quantities``
            the measured targets, or the error text of a run that failed.
        progress: receives :class:`engine.StudyProgress` (``run_key`` ``cal-NNN`` of
            :func:`calibration_runs` in all; with an executor, from its ``channel`` every
            ``poll_interval`` s); returning False stops the calibration with
            :class:`engine.StopRequested` (stored runs are kept: a rerun resumes).
        options: how the runs are run (:class:`engine.RunOptions`: executor, task threads,
            channel, poll interval, wall-time limit per run, backend; checkpoints are not
            kept, a run in flight starts again).
        resolution: the runs' cell is not the bulk: per kind of target (``porosity``,
            ``loading_stiffness``, ``unloading_stiffness``, ``strength``) a (factor, sd of
            its log) that takes a value in the cell to the bulk, e.g.
            :func:`resolution_corrections` of a study's resolution curve in the same cell
            (docs/CALIBRATION.md); each run's value is corrected before it meets the
            laboratory's, and the correction's sd adds to the laboratory's.
        shear_test: the shear cell of shear targets (``targets.shear``): an
            :class:`engine.ShearTest` (its law and stresses left out) or its fields but those
            as a dict, its particle radius the base test's; each yield locus runs it at its
            sigma_pre and sigma_n with the parameter set's law. None: docs/SHEAR.md's default
            cell, 10 x 5 x 15 diameters, of the base test's material
            (:func:`engine.calibration.forward.shear_cell`).
        vary_seed: each run packs its own sample: the tests' packing seed plus the run's
            index (0, 1, ...; the check run the next), so that the emulators' noise term
            holds the packing-to-packing scatter and their mean is the packings' mean, as a
            laboratory's targets (the mean of repeated tests) are. False (default): every
            run packs with the tests' own seed, as before (stored calibrations resume); a
            single packing's offset from the mean is then read as a change of the law
            (docs/CALIBRATION.md, the shear twin with kadh: mu_s's miss).
        discrepancy: where the model at its best misses the data by more than their stated
            errors (Birge ratio S > 1, :func:`model_discrepancy`), widen the laboratory and
            seed variances by S^2 before the posterior is sampled (default). False: the
            posterior as if the model could match the data exactly (a twin experiment, whose
            data the same model made); the ratio is reported either way.

    Uniaxial targets run the uniaxial test (its branches), shear targets one shear test
    per locus (:mod:`engine.calibration.forward`); a data set with both runs both for every
    parameter set, and every target is met against its own data and sd.

    Raises :class:`engine.ParameterError` naming a parameter it cannot set or a bad box."""
    from ..core.errors import StopRequested
    from ..study.run import RunOptions, StudyProgress

    stresses = check_request(base_test, targets, parameters, runs, shear_test)
    corrections = check_corrections(resolution)
    # the shear tests of the base law, one per locus (none without shear targets)
    cell = check_shear_cell(base_test, shear_test) if targets.shear else None
    shear = shear_tests(cell, targets, base_test.pair_law) if cell is not None else ()
    uniaxial = bool(stresses)
    options = options if options is not None else RunOptions()
    if executor is not None:
        options = replace(options, executor=executor)
    limit = (options.max_run_wall_time, options.wall_time_setting)
    law0 = base_test.pair_law
    axes = _axes(law0, parameters)
    total = calibration_runs(runs, waves, wave_runs)
    rng = np.random.default_rng(seed)
    d = len(axes)
    ok = lambda x: _feasible(law0, axes, x)  # noqa: E731
    folder = None if store is None else Path(store)
    if folder is not None:
        folder.mkdir(parents=True, exist_ok=True)
    done: list[tuple[np.ndarray, list[dict], int]] = []
    failed: list[dict] = []

    def ask(fraction: float, index: int, key: str, stage: str, time: float, msg: str = ""):
        if progress is None:
            return
        report = StudyProgress(min(fraction, 1.0), index, total, key, stage, time, msg)
        if progress(report) is False:
            if options.channel is not None:
                options.channel.request_stop()
            raise StopRequested(f"calibration stopped during run {key}")

    def execute(tests: list, keys: list[str], first: int, finished=None) -> dict[int, dict | str]:
        """Run ``tests`` (not stored), each stored as it ends and then told to
        ``finished(index, outcome)``; index -> outcome."""
        out: dict[int, dict | str] = {}
        if options.executor is None:
            for i, (k, t) in enumerate(zip(keys, tests)):
                j = first + i

                def here(p, j=j, k=k):
                    ask((j + p.fraction) / total, j, k, p.stage, p.time, p.message)

                here(_setup_progress())
                out[i] = _run_point(t, stresses, k, None, limit, options.backend, None, here)
                _save_point(folder, k, out[i], t)
                if finished is not None:
                    finished(i, out[i])
            return out
        channel = options.channel
        if channel is not None:
            channel.reset()
        futs = {
            options.executor.submit(
                _run_point,
                t,
                stresses,
                k,
                channel,
                limit,
                options.backend,
                options.task_threads,
            ): i
            for i, (k, t) in enumerate(zip(keys, tests))
        }

        def ended(i: int, fut) -> None:
            out[i] = fut.result()  # a stop (StopRequested) or a broken pool: raised
            _save_point(folder, keys[i], out[i], tests[i])
            if finished is not None:
                finished(i, out[i])
            ask((first + len(out)) / total, first + i, keys[i], "done", 0.0)

        def running(reports) -> None:
            frac = len(out) + sum(min(max(r["fraction"], 0.0), 1.0) for _, r in reports)
            i, r = min(reports, key=lambda ir: ir[1]["fraction"])
            msg = f"{len(reports)} runs in progress"
            ask((first + frac) / total, first + i, keys[i], r["stage"], float(r["time"]), msg)

        wait_tasks(futs, keys, channel, options.poll_interval, ended, running)
        return out

    def run_wave(us: np.ndarray, wave: int) -> None:
        start = len(done) + len(failed)
        tests = [
            _test(base_test, axes, x, shear, uniaxial, (start + i) if vary_seed else 0)
            for i, x in enumerate(us)
        ]
        keys = [f"cal-{start + i:03d}" for i in range(len(us))]
        outcomes: dict[int, dict | str] = {}
        measured: dict[int, list[dict]] = {}

        def heard(i: int, outcome) -> None:
            # each run is measured and told to on_run as soon as it is stored (or found)
            outcomes[i] = outcome
            if not isinstance(outcome, str):
                measured[i] = _corrected(measure(outcome, base_test, targets), corrections)
            if on_run is not None:
                on_run(start + i, outcome if isinstance(outcome, str) else measured[i])

        todo = []
        for i, (k, t) in enumerate(zip(keys, tests)):
            if isinstance(t, str):  # a law the test refuses (e.g. too soft): not run
                heard(i, t)
                continue
            stored = _load_point(folder, k, stresses, t)
            if stored is not None:
                heard(i, stored)
            else:
                todo.append(i)
        execute(
            [tests[i] for i in todo],
            [keys[i] for i in todo],
            start + len(outcomes),
            lambda j, outcome: heard(todo[j], outcome),
        )
        for i in range(len(us)):  # in the wave's order, however the runs ended
            if isinstance(outcomes[i], str):  # failed: left out of the emulators
                failed.append(
                    {
                        "wave": wave,
                        "parameters": {a.name: a.value(float(x)) for a, x in zip(axes, us[i])},
                        "error": outcomes[i],
                    }
                )
            else:
                done.append((us[i], measured[i], wave))

    run_wave(_maximin(rng, runs, d, ok), 0)
    if len(done) < d + 2:
        raise ParameterError(
            "calibrate.parameters",
            parameters,
            "a box where most runs finish",
            f"{len(failed)} of {runs} design runs failed, e.g. {failed[0]['error']}",
        )
    quantities = done[0][1]
    z, lab_var = _log_lab(quantities)
    lab = np.array([q["lab"] for q in quantities])

    def data():
        u = np.array([x for x, _, _ in done])
        y = np.array([[q["value"] for q in qs] for _, qs, _ in done])
        return u, _floor_log(y, lab)

    short = _short_quantities(quantities, data()[1], d)
    if short:
        raise ParameterError(
            "calibrate.targets",
            "strength",
            "targets the design runs give values for",
            "; ".join(short)
            + ": a strength target needs a consolidation stress and a law whose samples fail",
        )

    for wave in range(1, waves + 1):
        u, y = data()
        gps = _emulators(u, y)
        cand = rng.random((20000, d))
        mu, var, noise = _predict(gps, cand)
        imp = np.max(np.abs(mu - z) / np.sqrt(var + lab_var + noise), axis=1)
        keep = np.nonzero(imp < IMPLAUSIBLE)[0]
        if keep.size < wave_runs:
            keep = np.argsort(imp)[: max(wave_runs * 20, 200)]
        keep = np.array([k for k in keep if ok(cand[k])], dtype=int)  # laws it can make
        if keep.size == 0:
            break
        # the least implausible first, then each next as far as it can be from those chosen
        # and from the runs so far
        chosen = [int(keep[np.argmin(imp[keep])])]
        dmin = np.sqrt(((cand[keep] - cand[chosen[0]]) ** 2).sum(1))
        dmin = np.minimum(dmin, np.sqrt(((cand[keep][:, None] - u[None]) ** 2).sum(-1)).min(1))
        while len(chosen) < min(wave_runs, keep.size):
            k = int(np.argmax(dmin))
            chosen.append(int(keep[k]))
            dmin = np.minimum(dmin, np.sqrt(((cand[keep] - cand[keep[k]]) ** 2).sum(1)))
        run_wave(cand[chosen], wave)

    u, y = data()
    gps = _emulators(u, y)
    samples = _metropolis(gps, z, lab_var, d, rng)
    fit = model_discrepancy(gps, z, lab_var, samples, quantities, d)
    if discrepancy and fit["scale"] > 1.0:
        # the model cannot match the data within their stated errors: widen them by the
        # Birge ratio, so that the posterior claims no more than the model can match
        s2 = fit["scale"] ** 2
        noise_q = np.array([g.noise for g in gps])
        samples = _metropolis(gps, z, s2 * lab_var + (s2 - 1.0) * noise_q, d, rng)
        fit["applied"] = True
    med = np.median(samples, axis=0)
    law = _law(law0, axes, med)
    params = {}
    for i, a in enumerate(axes):
        lo, hi = np.quantile(samples[:, i], [0.05, 0.95])
        ratio = float(samples[:, i].std() / (1 / math.sqrt(12)))
        params[a.name] = {
            "median": a.value(float(med[i])),
            "interval": [a.value(float(lo)), a.value(float(hi))],
            "box": [a.lo, a.hi],
            "spread_ratio": ratio,
            "status": "determined" if ratio < DETERMINED else "free",
            "unit": describe_unit(law0, a.name),
        }
    posterior = _posterior(samples, axes)
    sens = _sobol(gps, quantities, axes, rng)
    try:
        check_test = replace(base_test, pair_law=law)
    except ParameterError:  # shear data alone: a law the uniaxial test refuses, never run
        check_test = None
    check_run = _test(
        base_test, axes, med, shear, uniaxial, len(done) + len(failed) if vary_seed else 0
    )
    if isinstance(check_run, str):  # a law a shear test refuses: the check is not run
        checked = check_run
    else:
        checked = _load_point(folder, "check", stresses, check_run)
        if checked is None:
            checked = execute([check_run], ["check"], total - 1)[0]
    if isinstance(checked, str):
        check = [{**q, "value": math.nan} for q in quantities]
    else:
        check = _corrected(measure(checked, base_test, targets), corrections)
    noise = np.array([g.noise for g in gps])
    met, missed = [], []
    for j, q in enumerate(check):
        # laboratory, seed (log, as relative) and resolution correction (relative) together
        corr = q.get("correction_sd", 0.0) * q["lab"]
        sd = math.sqrt(q["sd"] ** 2 + noise[j] * q["lab"] ** 2 + corr**2)
        zscore = (q["value"] - q["lab"]) / sd if sd > 0 else math.inf
        if not math.isfinite(q["value"]):  # the check run failed, or its sample hardened
            met.append({**q, "seed_sd": math.sqrt(noise[j]) * q["lab"], "z": None, "met": False})
            if q.get("no_peak"):
                missed.append(
                    f"{q['name']}: the check run's sample did not fail at a peak (it hardened "
                    "to the strain limit: no strength; docs/FAILURE.md)"
                )
            else:
                missed.append(f"{q['name']}: the check run failed ({checked})")
            continue
        row = {**q, "seed_sd": math.sqrt(noise[j]) * q["lab"], "z": zscore, "met": abs(zscore) <= 2}
        met.append(row)
        if not row["met"]:
            missed.append(
                f"{q['name']}: {q['value']:.4g} against {q['lab']:.4g} +/- {sd:.2g} "
                f"({100 * (q['value'] / q['lab'] - 1):+.1f} %, z = {zscore:+.1f})"
            )
    run_rows = failed + [
        {
            "wave": w,
            "parameters": {a.name: a.value(float(x)) for a, x in zip(axes, ux)},
            "quantities": qs,
        }
        for ux, qs, w in done
    ]
    return Calibration(
        law,
        params,
        met,
        sens,
        run_rows,
        missed,
        _curves(checked),
        dict(corrections),
        posterior,
        check_test,
        cell_summary(shear[0]) if shear else None,
        fit,
    )


def model_discrepancy(gps, z, lab_var, samples, quantities, d: int) -> dict:
    r"""How far the model, at its best, is from the data: the Birge ratio (Birge 1932; the
    Particle Data Group's scale factor) of the emulators' means at the posterior median,

    .. math:: S^2 = \frac{1}{m - d} \sum_j \frac{(\mu_j - z_j)^2}{V_j + \sigma_j^2 +
              \nu_j},

    over the m targets (logs) with d parameters. A model that can match the data within
    their stated errors (laboratory sd, seed scatter, emulator variance) gives S near 1; a
    real powder a sphere model cannot match gives S > 1, and :func:`calibrate` then widens
    the laboratory and seed variances by S^2 (``scale`` S) and samples the posterior again,
    so that its intervals claim no more than the model can match (an inflation stated in the
    result, in place of a model-discrepancy term whose size nobody knows before the fit).
    With no more targets than parameters (m <= d) S cannot be estimated: ``scale`` 1.
    Returns ``ratio`` (S^2 or None), ``dof`` (m - d), ``scale`` (max(1, S)), ``applied``
    (False here; :func:`calibrate` sets it), and ``worst`` (the three targets that
    contribute most, name and standardised residual)."""
    med = np.median(samples, axis=0)[None]
    mu, var, noise = _predict(gps, med)
    r = (mu[0] - z) / np.sqrt(var[0] + lab_var + noise)
    dof = len(z) - d
    order = np.argsort(-np.abs(r))[:3]
    worst = [{"name": quantities[j]["name"], "z": float(r[j])} for j in order]
    if dof < 1:
        return {"ratio": None, "dof": dof, "scale": 1.0, "applied": False, "worst": worst}
    ratio = float(np.sum(r**2) / dof)
    return {
        "ratio": ratio,
        "dof": dof,
        "scale": max(1.0, math.sqrt(ratio)),
        "applied": False,
        "worst": worst,
    }


#: Posterior samples kept in the result (evenly thinned).
POSTERIOR_SAMPLES = 400


def _posterior(samples: np.ndarray, axes: list[_Axis]) -> dict:
    """The posterior as the result carries it: :data:`POSTERIOR_SAMPLES` samples, evenly
    thinned, in the law's units (a row per sample, a column per parameter), and the
    correlation matrix of the parameters in the box's scale (log where the box is): a
    correlation near +-1 is a pair the data determine only together (e.g. mu_s and mu_r
    through density and strength)."""
    keep = samples[
        np.linspace(0, len(samples) - 1, min(POSTERIOR_SAMPLES, len(samples))).astype(int)
    ]
    values = [[a.value(float(x)) for a, x in zip(axes, row)] for row in keep]
    if samples.shape[1] > 1:
        with np.errstate(invalid="ignore", divide="ignore"):
            corr = np.corrcoef(samples, rowvar=False)
        corr = np.where(np.isfinite(corr), corr, 0.0)
    else:
        corr = np.ones((1, 1))
    return {
        "parameters": [a.name for a in axes],
        "samples": values,
        "correlation": [[float(c) for c in row] for row in corr],
    }


def _metropolis(gps, z, lab_var, d: int, rng, chains: int = 8, steps: int = 4000) -> np.ndarray:
    """Posterior samples in the unit cube (uniform prior), random-walk Metropolis with the
    step tuned during burn-in towards a quarter of proposals accepted."""

    def logp(x):
        inside = np.all((x >= 0) & (x <= 1), axis=1)
        mu, var, noise = _predict(gps, np.clip(x, 0, 1))
        tot = var + lab_var + noise
        lp = -0.5 * np.sum((mu - z) ** 2 / tot + np.log(tot), axis=1)
        return np.where(inside, lp, -np.inf)

    x = rng.random((chains, d))
    lp = logp(x)
    step = np.full(chains, 0.1)
    kept = []
    for s in range(steps):
        prop = x + step[:, None] * rng.normal(size=(chains, d))
        lq = logp(prop)
        acc = np.log(rng.random(chains)) < lq - lp
        x[acc], lp[acc] = prop[acc], lq[acc]
        if s < steps // 2:
            step *= np.where(acc, 1.05, 0.985)
        elif s % 4 == 0:
            kept.append(x.copy())
    return np.concatenate(kept)


def _sobol(gps, quantities, axes, rng, n: int = 2048) -> dict:
    """First-order Sobol index of each parameter for each quantity's emulator mean (Saltelli
    2010: S_i = mean(f(B) (f(A_B^i) - f(A))) / var), on outputs centred by their mean: the
    estimator's scatter grows with the mean, and a log stiffness of about 14 with a variance
    of a few tenths gave an index of 0.6 to a parameter that does not move it."""
    from scipy.stats import qmc

    d = len(axes)
    # the two sample matrices from one scrambled Sobol sequence in 2d dimensions (Saltelli
    # 2010 section 3: quasi-random points converge faster than random ones)
    ab = qmc.Sobol(2 * d, scramble=True, seed=rng).random_base2(math.ceil(math.log2(n)))
    a, b = ab[:, :d], ab[:, d:]
    fa, fb = (_predict(gps, m)[0] for m in (a, b))
    both = np.vstack([fa, fb])
    centre, var = both.mean(axis=0), both.var(axis=0)
    fa, fb = fa - centre, fb - centre
    out = {q["name"]: {} for q in quantities}
    for i, ax in enumerate(axes):
        abi = a.copy()
        abi[:, i] = b[:, i]
        fab = _predict(gps, abi)[0] - centre
        s = np.mean(fb * (fab - fa), axis=0) / np.where(var > 0, var, 1.0)
        for j, q in enumerate(quantities):
            out[q["name"]][ax.name] = float(np.clip(s[j], 0.0, 1.0))
    return out


def _setup_progress():
    from ..uniaxial.results import Progress

    return Progress(0.0, "setup", 0.0, 0.0, 0, "building the packing")


def _digest(test: UniaxialTest | Forward) -> str:
    """A short digest of a test (a failed run's file names its test: an error text cannot)."""
    import hashlib
    import json

    return hashlib.sha1(json.dumps(test.to_dict(), sort_keys=True).encode()).hexdigest()[:10]


def _save_point(
    folder: Path | None, key: str, results: dict | str, test: UniaxialTest | Forward
) -> None:
    if folder is None:
        return
    if isinstance(results, str):
        save_run(folder / f"{key}-failed-{_digest(test)}.h5", results)
        return
    for s, r in _uniaxial(results).items():
        save_run(folder / f"{key}-{s:g}Pa.h5", r, keep_particles=False)
    if SHEAR in results:
        store_loci(folder, key, results[SHEAR])


def _load_point(
    folder: Path | None, key: str, stresses, test: UniaxialTest | Forward
) -> dict | None:
    if folder is None:
        return None
    bad = folder / f"{key}-failed-{_digest(test)}.h5"
    if bad.exists():  # the parameter set is the design's: the same key, the same test
        return load_run(bad)
    out = {}
    if isinstance(test, Forward):
        if test.shear:
            shear = stored_loci(folder, key, test.shear)
            if shear is None:
                return None
            out[SHEAR] = shear
        if test.uniaxial is None:
            return out
        test = test.uniaxial
    for s in stresses:
        p = folder / f"{key}-{s:g}Pa.h5"
        if not p.exists():
            return None
        r = load_run(p)
        if isinstance(r, str) or r.test != replace(test, consolidation_stress=s):
            return None
        out[s] = r
    return out


__all__ = [
    "CALIBRATED",
    "Calibration",
    "branch_stresses",
    "calibrate",
    "calibration_runs",
    "check_corrections",
    "check_request",
    "measure",
    "resolution_corrections",
]
