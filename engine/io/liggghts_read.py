"""A LIGGGHTS run of an exported deck read back as demscale's run record
(docs/LIGGGHTS_DECK.md).

:func:`read_output` turns what the deck of :mod:`engine.io.liggghts_deck` wrote
(``curves.txt``, ``stage_<name>.dump``, ``log.liggghts``) into an
:class:`engine.UniaxialResult` of the deck's test: the same curves, computed from the deck's
raw columns with demscale's formulas (engine.uniaxial.driver, engine.uniaxial.measures),
the stage-end particles, and the scalars of a demscale run (stiffnesses, K0, porosities,
strength and failure, run statistics). :func:`save_output` stores it with
:func:`engine.io.store.save_run` in the one HDF5 layout of a run, so that every metric,
verdict and plot of demscale reads it as it reads its own runs.

Conversions (checked against demscale on one packing by tests/test_liggghts_deck_run.py):
stresses are forces over Lx Ly; the pair stress is minus LIGGGHTS' per-atom pair stress
summed over the particles, over the sample's volume Lx Ly h; ``contact/atom`` counts
every contact at both of its particles, as demscale's contact counts do.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np

from ..simulation.packing import sphere_volume
from ..uniaxial.driver import LOADING, StageError, stages_of
from ..uniaxial.measures import (
    FailureDetector,
    held_inertial_numbers,
    interior_margin,
    lateral_ratio,
    secant_slope,
    strength_curve,
    strength_scalars,
)
from ..uniaxial.results import CURVE_UNITS, StageResult, UniaxialResult
from ..uniaxial.spec import UniaxialTest
from .liggghts_deck import COLUMNS, CURVES, DATA, LOG, STAGE_DUMP, STAGES, TEST


class OutputError(ValueError):
    """A deck folder whose output is missing, unfinished or not the deck's."""


def read_test(directory) -> UniaxialTest:
    """The test a deck folder was written for (its ``test.json``)."""
    path = Path(directory) / TEST
    try:
        return UniaxialTest.from_dict(json.loads(path.read_text()))
    except OSError as e:
        raise OutputError(f"{path}: {e}; not a deck folder of engine.io.liggghts_deck") from None


def read_radii(directory) -> np.ndarray:
    """The radii [m] of the deck's packing, in atom id order (its ``packing.data``)."""
    text = (Path(directory) / DATA).read_text().splitlines()
    start = text.index("Atoms") + 2
    rows = []
    for line in text[start:]:
        if not line.strip():
            break
        f = line.split()
        rows.append((int(f[0]), float(f[2]) / 2))
    rows.sort()
    return np.array([r for _, r in rows])


def parse_curves(text: str) -> dict:
    """The stages of a ``curves.txt``: ``stages`` maps a stage's name to its ``begin`` step,
    ``h0`` [m], ``rows`` (samples x :data:`COLUMNS`) and ``end`` step (None while it runs);
    ``failed`` (the step the failure detector fired, or None), ``error`` (the stage error's
    fields, or None) and ``done`` (whether the deck reached its end)."""
    stages: dict[str, dict] = {}
    out = {"stages": stages, "failed": None, "error": None, "done": False}
    ncol = len(COLUMNS)
    for number, line in enumerate(text.splitlines(), start=1):
        f = line.split()
        if not f:
            continue
        if f[0] == "#":
            kind = f[1] if len(f) > 1 else ""
            if kind == "begin":
                stages[f[2]] = {"begin": int(f[3]), "h0": float(f[4]), "rows": [], "end": None}
            elif kind == "end":
                stages[f[2]]["end"] = int(f[3])
            elif kind == "failed":
                out["failed"] = int(f[2])
            elif kind == "error":
                out["error"] = {
                    "stage": f[2],
                    "step": int(f[3]),
                    "stress": float(f[4]),
                    "gap": float(f[5]),
                    "kinetic_energy": float(f[6]),
                }
            elif kind == "done":
                out["done"] = True
            continue
        if len(f) != ncol:
            raise OutputError(f"{CURVES} line {number}: {len(f)} values, not {ncol}")
        stage = STAGES[int(f[0])]
        if stage not in stages:
            raise OutputError(f"{CURVES} line {number}: a sample of {stage} before its begin")
        stages[stage]["rows"].append([float(v) for v in f])
    for s in stages.values():
        s["rows"] = np.array(s["rows"], dtype=float).reshape(-1, ncol)
    return out


def read_dump(path) -> tuple[np.ndarray, np.ndarray]:
    """Positions (N, 3) [m] and radii (N,) [m] of a ``write_dump ... id x y z radius``
    file, in atom id order."""
    lines = Path(path).read_text().splitlines()
    k = next(i for i, t in enumerate(lines) if t.startswith("ITEM: ATOMS"))
    a = np.array([[float(v) for v in t.split()] for t in lines[k + 1 :] if t.strip()])
    a = a[np.argsort(a[:, 0])]
    return a[:, 1:4].copy(), a[:, 4].copy()


def loop_seconds(log: str) -> tuple[float, int]:
    """The seconds LIGGGHTS spent in its run loops (the sum of its ``Loop time`` lines,
    set-ups left out as demscale leaves out compilation) and its MPI ranks."""
    found = re.findall(r"Loop time of (\S+) on (\d+) procs", log)
    return sum(float(s) for s, _ in found), max((int(p) for _, p in found), default=1)


def stage_curves(test: UniaxialTest, stage: str, rows: np.ndarray, h0: float, radii) -> dict:
    """demscale's curves of one stage (:data:`engine.uniaxial.results.CURVE_UNITS`) from the
    deck's raw columns ``rows`` (samples x :data:`COLUMNS`), with the stage's reference
    height ``h0`` [m] and the packing's ``radii`` [m]."""
    c = {k: rows[:, i] for i, k in enumerate(COLUMNS)}
    dt = test.resolved_dt()
    area = test.cell[0] * test.cell[1]
    n = len(radii)
    rmax = float(np.max(radii))
    gap = c["ztop"]
    volume = area * gap
    s_top = c["ftop"] / area
    s_bot = c["fbot"] / area
    moving = stage in ("pre_compression", "consolidation", "unloading", "unconfined")
    speed = test.platen_speed if moving else 0.0
    layer = test.density * test.gravity * 2 * test.radius
    p = np.maximum(np.maximum(np.abs(s_top), np.abs(s_bot)), layer)
    margin = np.array([interior_margin(test.margin, float(g), rmax) for g in gap])
    slab = area * (gap - 2 * margin)
    n_in = c["interior_n"]
    lever_b = np.where(
        c["touch_bottom"] > 0, c["lever_bottom"] / np.maximum(c["touch_bottom"], 1), 0
    )
    lever_t = np.where(c["touch_top"] > 0, c["lever_top"] / np.maximum(c["touch_top"], 1), 0)
    platen = np.abs(c["fbot"]) * lever_b + np.abs(c["ftop"]) * lever_t
    out = {
        "time": c["step"] * dt,
        "strain": (h0 - gap) / h0,
        "stress_top": s_top,
        "stress_bottom": s_bot,
        "porosity": 1.0 - float(sphere_volume(radii).sum()) / volume,
        "coordination": c["contacts"] / n,
        "kinetic_energy": c["ke_trans"] + c["ke_rot"],
        "inertial_number": speed / gap * 2.0 * test.radius * np.sqrt(test.density / p),
        "platen_gap": gap.copy(),
        "porosity_interior": 1.0 - c["slab_solid"] / slab,
        "coordination_interior": np.where(
            n_in > 0, c["interior_contacts"] / np.maximum(n_in, 1), 0.0
        ),
        "stress_lateral": -0.5 * (c["stress_xx"] + c["stress_yy"]) / volume,
        "stress_vertical": (-c["stress_zz"] + platen) / volume,
        "stress_interior": np.where(
            slab > 0, -c["interior_stress_zz"] / np.where(slab > 0, slab, 1.0), 0.0
        ),
    }
    for k, v in out.items():
        if not np.all(np.isfinite(v)):
            raise OutputError(f"stage {stage}: non-finite values in the {k} curve")
    return {k: np.asarray(out[k], dtype=float) for k in CURVE_UNITS}


def read_output(directory) -> UniaxialResult:
    """The LIGGGHTS run in the deck folder ``directory`` as an :class:`engine.UniaxialResult`
    of the deck's test (module docstring). Raises :class:`engine.uniaxial.driver.StageError`
    when the deck stopped at a stage's bound (``max_stage_time``), as demscale's run would,
    and :class:`OutputError` when the output is missing or unfinished."""
    directory = Path(directory)
    test = read_test(directory)
    try:
        parsed = parse_curves((directory / CURVES).read_text())
    except OSError as e:
        raise OutputError(f"{directory / CURVES}: {e}; has LIGGGHTS run the deck?") from None
    err = parsed["error"]
    if err is not None:
        begin = parsed["stages"].get(err["stage"], {}).get("begin", 0)
        steps = err["step"] - begin
        raise StageError(
            f"LIGGGHTS: stage {err['stage']} did not reach its criterion within {steps} steps "
            f"({steps * test.resolved_dt():.3g} s, max_stage_time); then: top stress "
            f"{err['stress']:.4g} Pa, platen gap {err['gap']:.4g} m, kinetic energy "
            f"{err['kinetic_energy']:.3g} J",
            err["stage"],
            steps,
        )
    if not parsed["done"]:
        raise OutputError(f"{directory / CURVES}: the deck has not finished (no 'done' line)")
    radii = read_radii(directory)
    stages: dict[str, StageResult] = {}
    for name, s in parsed["stages"].items():
        if s["end"] is None or len(s["rows"]) == 0:
            raise OutputError(f"{directory / CURVES}: stage {name} has no end")
        curves = stage_curves(test, name, s["rows"], s["h0"], radii)
        dump = directory / STAGE_DUMP.format(name)
        pos, rad = read_dump(dump) if dump.exists() else (None, None)
        stages[name] = StageResult(name, curves, pos, rad, s["end"] - s["begin"])
    expected = list(stages_of(test))
    if list(stages) != expected:
        raise OutputError(f"{directory / CURVES}: stages {list(stages)}, not {expected}")
    log = directory / LOG
    seconds, ranks = loop_seconds(log.read_text()) if log.exists() else (0.0, 1)
    solid = float(sphere_volume(radii).sum())
    return UniaxialResult(test, stages, scalars(test, stages, len(radii), solid, seconds, ranks))


def scalars(test, stages: dict, n: int, solid: float, seconds: float, ranks: int) -> dict:
    """The scalars of a demscale run (engine.uniaxial.driver ``finish``) from the stages
    read back: ``n`` particles of ``solid`` volume [m^3], ``seconds`` of LIGGGHTS' run loops
    on ``ranks`` MPI ranks (in ``wall_time`` and ``threads``; ``setup_time`` 0)."""
    s: dict[str, float] = {}
    cons, unl = stages["consolidation"].curves, stages["unloading"].curves
    s["loading_stiffness"] = secant_slope(cons["strain"], cons["stress_top"], 0.5, 1.0)
    s["unloading_stiffness"] = secant_slope(unl["strain"][::-1], unl["stress_top"][::-1], 0.5, 1.0)
    s["k0"] = lateral_ratio(cons["stress_top"], cons["stress_lateral"])
    s["consolidated_porosity"] = float(cons["porosity"][-1])
    s["consolidated_porosity_interior"] = float(cons["porosity_interior"][-1])
    dmax = 2 * test.radius * (1 + test.polydispersity)
    s["thickness_diameters"] = test.thickness_diameters
    gap = float(cons["platen_gap"][-1])
    s["height_diameters"] = gap / dmax
    s["interior_margin"] = interior_margin(test.margin, gap, dmax / 2)
    if "unconfined" in stages:
        u = stages["unconfined"].curves
        # the detector replayed on the strength curve's samples (the deck's own copy stopped
        # the stage on the same sample)
        det = FailureDetector(test.failure_drop, test.failure_strain)
        fired = any(det.update(e, x) for e, x in zip(u["strain"], strength_curve(test, u)))
        area = test.cell[0] * test.cell[1]
        g = 0.0 if test.gravity_off_after_fill else test.gravity
        s.update(strength_scalars(u, test, fired, test.density * solid * g / (2.0 * area)))
    last = sum(st.steps for st in stages.values())
    s["particles"] = float(n)
    s["steps"] = float(last)
    ts = test.time_step()
    s["dt"] = ts.dt
    s["dt_fraction"] = ts.dt / ts.critical
    s["dt_critical"] = ts.critical
    s["dt_limited_by_wall"] = 1.0 if ts.kind == "wall" else 0.0
    s["impact_speed"] = ts.impact_speed
    held = np.concatenate(
        [held_inertial_numbers(stages[k].curves, test) for k in LOADING if k in stages]
    )
    s["inertial_number_held"] = float(np.median(held))
    s["inertial_number_held_max"] = float(np.max(held))
    s["setup_time"] = 0.0
    s["wall_time"] = seconds
    s["particle_steps"] = s["particles"] * last
    s["threads"] = float(ranks)
    s["max_inertial_number"] = max(
        float(np.max(stages[k].curves["inertial_number"])) for k in LOADING if k in stages
    )
    bad = [k for k, v in s.items() if not math.isfinite(v)]
    if bad:
        raise OutputError(f"non-finite scalars {bad}: the run is not usable")
    return s


def save_output(directory, path) -> Path:
    """Store the LIGGGHTS run of the deck folder ``directory`` at ``path`` in demscale's
    HDF5 layout of a run (:func:`engine.io.store.save_run`; a run that stopped at a stage's
    bound is stored as its error text, as demscale stores a failed run), with the attribute
    ``producer`` naming LIGGGHTS and the deck folder."""
    import h5py

    from .store import save_run

    try:
        outcome = read_output(directory)
    except StageError as e:
        outcome = str(e)
    path = save_run(Path(path), outcome)
    with h5py.File(path, "r+") as f:
        if isinstance(outcome, str):  # the failed run's test, as a finished one has it
            f.attrs["test"] = json.dumps(read_test(directory).to_dict())
        f.attrs["producer"] = json.dumps(
            {"code": "LIGGGHTS 3.8", "deck": "engine.io.liggghts_deck", "folder": str(directory)}
        )
    return path


def judge_runs(runs: list, references: list, tolerances: dict | None = None, confidence=None):
    """LIGGGHTS' runs of a test (``runs``: :class:`engine.UniaxialResult` or error texts)
    judged against demscale's runs of the test it stands for (``references``), as a study
    judges a coarse variant against its references: every verdict metric's error, its
    interval at the study's confidence and the verdict (engine.study.judge.judge_groups,
    metric values by engine.study.metrics.metric_values; ``tolerances`` override
    engine.DEFAULT_TOLERANCES). The reference's test sets the stress levels, tolerances and
    consolidation stress; runs that stopped (error texts) are left out and counted.

    Returns {verdict, reason, metrics (per metric: error, signed_error, interval, verdict,
    ...), seeds, reference_seeds, failed (the error texts), radius, noise (the references'
    spread per metric)}."""
    from types import SimpleNamespace

    from ..core.errors import ParameterError
    from ..study.judge import CONFIDENCE, judge_groups
    from ..study.metrics import DEFAULT_TOLERANCES, metric_names, metric_values

    done = [r for r in runs if not isinstance(r, str)]
    failed = [r for r in runs if isinstance(r, str)]
    refs = [r for r in references if not isinstance(r, str)]
    if len(refs) < 2:
        raise ValueError(f"{len(refs)} finished reference run(s): a verdict needs at least 2")
    tol = dict(DEFAULT_TOLERANCES)
    for k, v in (tolerances or {}).items():
        if k not in tol:
            raise ParameterError("tolerances", k, f"a metric among {sorted(tol)}")
        if not 0 < v <= 1:
            raise ParameterError(f"tolerances.{k}", v, "in (0, 1]")
        tol[k] = float(v)
    confidence = CONFIDENCE if confidence is None else float(confidence)
    if not 0.5 <= confidence < 1:
        raise ParameterError("confidence", confidence, "in [0.5, 1)")
    base = refs[0].test
    # what the study's verdict rule reads of a study: its reference, tolerances, confidence
    spec = SimpleNamespace(reference=base, tolerances=tol, confidence=confidence)
    radius = float(done[0].test.radius) if done else float(base.radius)
    out = {
        "radius": radius,
        "seeds": len(done),
        "reference_seeds": len(refs),
        "failed": failed,
    }
    if not done:
        out.update(
            verdict="not judged",
            reason=f"every one of the {len(failed)} LIGGGHTS run(s) stopped: "
            + (failed[0] if failed else "none given"),
            metrics=[],
            noise={},
        )
        return out
    names = metric_names(base.unconfined and all("unconfined" in r.stages for r in done))
    noise, verdicts = judge_groups(
        spec,
        [metric_values(r) for r in refs],
        {(radius, "liggghts"): [metric_values(r) for r in done]},
        names,
    )
    v = verdicts[0]
    out.update(verdict=v["verdict"], reason=v["reason"], metrics=v["metrics"], noise=noise)
    return out


__all__ = [
    "OutputError",
    "judge_runs",
    "loop_seconds",
    "parse_curves",
    "read_dump",
    "read_output",
    "read_radii",
    "read_test",
    "save_output",
    "stage_curves",
]
