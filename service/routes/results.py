"""Result endpoints of a succeeded study: summary, JSON curves, PNG plots, the HDF5 file."""

from __future__ import annotations

from fastapi import APIRouter, HTTPException, Query, Response
from fastapi.responses import FileResponse

from .. import h5store
from ..deps import ResultsDep, StudyDep
from ..plots import KINDS, plot_png

router = APIRouter(prefix="/studies/{study_id}", tags=["results"])


@router.get("/summary")
def summary(study: StudyDep, results: ResultsDep) -> dict:
    """Per run: radius, rule, particles, steps, dt, wall time, speed-up and errors against
    the reference; the spread over seeds; the advisor's answer; units of every column."""
    return {"id": str(study.id), "name": study.name, **h5store.read_summary(results)}


@router.get("/curves")
def curves(
    study: StudyDep,
    results: ResultsDep,
    run: str | None = Query(None, description="Run key; all runs when left out."),
    kind: str = Query("all", description="A stage name, or 'all'."),
) -> dict:
    """Curves of a run (or every run), of one stage or all: lists of numbers with units."""
    try:
        data = h5store.read_runs(results, run, None if kind == "all" else kind, with_units=True)
    except KeyError as e:
        raise HTTPException(status_code=404, detail=e.args[0]) from e
    for entry in data["runs"].values():
        entry["stages"] = {
            s: {k: v.tolist() for k, v in c.items()} for s, c in entry["stages"].items()
        }
    return {"id": str(study.id), **data}


@router.get(
    "/plots/{kind}.png", response_class=Response, responses={200: {"content": {"image/png": {}}}}
)
def plot(kind: str, study: StudyDep, results: ResultsDep) -> Response:
    """A PNG plot: stress_strain, stress_porosity, coordination, unconfined or
    error_vs_runtime; 404 for any other kind."""
    if kind not in KINDS:
        raise HTTPException(status_code=404, detail=f"no plot {kind!r}; plots: {list(KINDS)}")
    return Response(plot_png(results, kind), media_type="image/png")


@router.get("/results.h5", response_class=FileResponse)
def results_file(study: StudyDep, results: ResultsDep) -> FileResponse:
    """The study's HDF5 file (layout in docs/SERVICE.md)."""
    return FileResponse(
        results, media_type="application/x-hdf5", filename=f"demscale-{study.id}.h5"
    )
