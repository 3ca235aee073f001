"""The planner's endpoint: how coarse a process may go, per feature kind (engine.process;
docs/RESOLUTION.md). A plan reads the stored size series' evidence and runs nothing, so it
is answered at once, not queued."""

from __future__ import annotations

from fastapi import APIRouter
from fastapi.exceptions import RequestValidationError

import engine

from ..admission import _error
from ..errors import answers
from ..spec import jsonable, record_model

router = APIRouter(prefix="/plans", tags=["plans"], responses=answers(401))

#: The request: an :class:`engine.Process`'s declared fields (its pair law with its
#: ``type``), unknown fields refused.
PlanCreate = record_model(engine.Process)


@router.post("", responses=answers(400, 413, 429))
def make_plan(body: PlanCreate) -> dict:  # type: ignore[valid-type]
    """The largest coarse-graining factor s_max = L / (N_req d0) of the process per feature
    kind (the process's own kind first), with the evidence (the stored size series whose
    law matches), the coarse model at s_max (law, time step, inertial and Bond numbers,
    particles per cubic metre, cost, LIGGGHTS fragment), and "not measured" with the reason
    where no series decides it. 422 naming the field for a process the engine refuses (a
    negative width, an unknown feature kind, a law it cannot scale)."""
    data = body.model_dump(exclude_unset=True)
    try:
        plan = engine.plan_process(engine.Process.from_dict(data))
    except engine.ParameterError as e:
        field = e.field.split(".", 1)[1] if "." in e.field else e.field
        raise RequestValidationError([_error(tuple(field.split(".")), str(e), e.value)]) from e
    return jsonable(plan.to_dict())
