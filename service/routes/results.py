"""Result endpoints of a succeeded study: summary, JSON curves, PNG plots, the HDF5 file."""

from __future__ import annotations

from enum import Enum
from typing import Annotated

import numpy as np
from fastapi import APIRouter, HTTPException, Path, Query, Response
from fastapi.responses import FileResponse

from engine.io.store import HOPPER_STAGE
from engine.io.vtkhdf import render_section
from engine.shear.spec import MAX_POINTS
from engine.uniaxial.driver import STAGES

from .. import h5store
from ..deps import ResultsDep, SettingsDep, StudyDep, get_results
from ..errors import answers
from ..plots import KINDS, not_a_kind_of, plot_png

router = APIRouter(prefix="/studies/{study_id}", tags=["results"], responses=answers(401, 404, 409))

#: The plots the API draws (engine.io.figures.KINDS).
PlotKind = Enum("PlotKind", {k: k for k in KINDS}, type=str)
#: The shear test's stages (engine.shear.driver): the pre-shear, then per shear point k the
#: reversal, the normal-stress stage and the shear to failure.
SHEAR_STAGES = (
    "preshear",
    *(f"point{k}_{part}" for k in range(MAX_POINTS) for part in ("reverse", "normal", "shear")),
)
#: A stage of the uniaxial test (engine.uniaxial.driver.STAGES; a shear test's fill and
#: consolidation are among them), of the shear test or of a hopper (its discharge, as
#: engine.io.store stores it), or every stage.
StageKind = Enum(
    "StageKind", {s: s for s in (*STAGES, *SHEAR_STAGES, HOPPER_STAGE, "all")}, type=str
)
#: How the curves are sent.
CurvesFormat = Enum("CurvesFormat", {k: k for k in ("json", "csv")}, type=str)
#: Longest run key accepted [characters].
RUN_KEY_MAX_LENGTH = 100


#: Snapshot file names: the ParaView files and a PNG section per stage.
SNAPSHOT_NAME = r"^((particles|contacts)(\.vtkhdf|\.pvd|-[0-9]{4}\.vtu)|[a-z_]+\.png)$"
#: The media type of each kind of snapshot file.
SNAPSHOT_MEDIA = {
    ".png": "image/png",
    ".vtkhdf": "application/x-hdf5",
    ".pvd": "application/xml",
    ".vtu": "application/xml",
}


@router.get("/summary")
def summary(study: StudyDep, results: ResultsDep, settings: SettingsDep) -> dict:
    """The answer first (what the study decided in one line, then the line that qualifies
    it); per run: radius, rule, particles, steps, dt, wall time, speed-up and errors against
    the reference; the spread over seeds; the report (verdicts, noise floor,
    warnings); units of every column; the snapshot files of every run."""
    snaps = {
        run: [f"/studies/{study.id}/runs/{run}/snapshots/{f}" for f in files]
        for run, files in settings.snapshot_files(study.id).items()
    }
    summary = h5store.read_summary(results)
    return {
        "answer": summary.pop("answer"),  # first: what the study decided, in a line
        "id": str(study.id),
        "name": study.name,
        **summary,
        "snapshots": snaps,
    }


@router.get(
    "/runs/{run}/snapshots/{name}",
    response_class=FileResponse,
    responses={
        200: {
            "content": {
                "application/x-hdf5": {"schema": {"type": "string", "format": "binary"}},
                "image/png": {"schema": {"type": "string", "format": "binary"}},
                "application/xml": {"schema": {"type": "string"}},
            },
            "description": "A VTKHDF file (ParaView 5.12+), a VTK XML file (.vtu, one time "
            "step) or its collection (.pvd, any ParaView), or a PNG section of a stage's end.",
        }
    },
)
def snapshot(
    study: StudyDep,
    settings: SettingsDep,
    run: Annotated[
        str,
        Path(
            max_length=RUN_KEY_MAX_LENGTH,
            pattern=r"^[A-Za-z0-9_.\-]+$",
            description="Run key, e.g. ref-s1.",
        ),
    ],
    name: Annotated[
        str,
        Path(
            max_length=64,
            pattern=SNAPSHOT_NAME,
            description="particles.vtkhdf, contacts.vtkhdf, particles.pvd, contacts.pvd, "
            "particles-NNNN.vtu, contacts-NNNN.vtu or <stage>.png",
        ),
    ],
) -> FileResponse:
    """A snapshot file of a run: the particles or the force chains at every stage end
    (temporal VTKHDF; docs/SNAPSHOTS.md), or the PNG section of one stage's end."""
    get_results(study, settings)  # 409 unless succeeded: after the path's own checks (422)
    if name not in settings.snapshot_files(study.id).get(run, []):
        raise HTTPException(status_code=404, detail=f"no snapshot {name!r} of run {run!r}")
    path = settings.snapshots_dir(study.id) / run / name
    if path.suffix == ".png" and not path.is_file():  # drawn on first request, then kept
        path = render_section(path.parent, path.stem)
    media = SNAPSHOT_MEDIA[path.suffix]
    # a .pvd names its .vtu files as they are in the run's folder: download them by name
    filename = name if path.suffix in (".pvd", ".vtu") else f"{run}-{name}"
    return FileResponse(path, media_type=media, filename=filename)


@router.get(
    "/curves",
    responses={
        200: {
            "content": {
                "application/json": {"schema": {"type": "object"}},
                "text/csv": {"schema": {"type": "string"}},
            }
        }
    },
)
def curves(
    study: StudyDep,
    settings: SettingsDep,
    run: Annotated[
        str | None,
        Query(
            max_length=RUN_KEY_MAX_LENGTH,
            pattern=r"^[A-Za-z0-9_.\-]+$",
            description="Run key (e.g. ref-s1); all runs when left out.",
        ),
    ] = None,
    kind: Annotated[StageKind, Query(description="A stage name, or 'all'.")] = StageKind.all,
    format: Annotated[
        CurvesFormat,
        Query(
            description="json: lists of numbers with units; csv: a row per sample, the "
            "run (without run=) and the stage first, each unit in its heading"
        ),
    ] = CurvesFormat.json,
):
    """Curves of a run (or every run), of one stage or all: lists of numbers with units (a
    sample not measured as null), or CSV. 404 for a run or stage the study does not have."""
    results = get_results(study, settings)  # 409 after the query's own checks (422)
    stage = None if kind is StageKind.all else kind.value
    try:
        data = h5store.read_runs(results, run, stage, with_units=True)
    except KeyError as e:
        raise HTTPException(status_code=404, detail=e.args[0]) from e
    if format is CurvesFormat.csv:
        from engine.io.curves import curves_csv, runs_csv

        if run is not None:
            text, name = curves_csv(data["runs"][run]["stages"]), f"{run}-curves.csv"
        else:
            text = runs_csv({k: v["stages"] for k, v in data["runs"].items()})
            name = f"{study.id}-curves.csv"
        return Response(
            text,
            media_type="text/csv",
            headers={"Content-Disposition": f'attachment; filename="{name}"'},
        )
    for entry in data["runs"].values():
        entry["stages"] = {
            s: {k: _json_values(v) for k, v in c.items()} for s, c in entry["stages"].items()
        }
    return {"id": str(study.id), **data}


def _json_values(values) -> list:
    """A curve as strict JSON: a sample not measured (NaN, e.g. a hopper's band speed where
    no grain is in the band) or infinite as null."""
    v = np.asarray(values)
    if v.dtype.kind != "f" or np.isfinite(v).all():
        return v.tolist()
    return np.where(np.isfinite(v), v, None).tolist()


@router.get(
    "/plots/{kind}.png",
    response_class=Response,
    responses={200: {"content": {"image/png": {"schema": {"type": "string", "format": "binary"}}}}},
)
def plot(
    kind: Annotated[PlotKind, Path(description="Which plot.")],
    study: StudyDep,
    settings: SettingsDep,
) -> Response:
    """A PNG plot of a kind the study has (its ``plot_kinds``): of a uniaxial study
    stress_strain, stress_porosity, coordination, unconfined (with that stage),
    error_vs_runtime and resolution (with resolution controls); of a shear study
    yield_locus, preshear, error_vs_runtime and resolution; of a hopper study
    error_vs_runtime and resolution. An unknown kind is a 422 and a
    kind the study does not have a 404 naming the kinds it has, whatever its status; one of
    its kinds of a study that has not succeeded a 409."""
    why = not_a_kind_of(study.spec, kind.value)
    if why is not None:
        raise HTTPException(status_code=404, detail=f"study {study.id}: {why}")
    results = get_results(study, settings)
    return Response(plot_png(results, kind.value), media_type="image/png")


@router.get(
    "/results.h5",
    response_class=FileResponse,
    responses={
        200: {
            "content": {"application/x-hdf5": {"schema": {"type": "string", "format": "binary"}}},
            "description": "The HDF5 file.",
        }
    },
)
def results_file(study: StudyDep, results: ResultsDep) -> FileResponse:
    """The study's HDF5 file (layout in docs/SERVICE.md)."""
    return FileResponse(
        results, media_type="application/x-hdf5", filename=f"demscale-{study.id}.h5"
    )
