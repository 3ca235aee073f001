"""The rows of a new job: a study (its row and a queued row per planned run) from its
admission, and a calibration (its row; its runs get rows as they start)."""

from __future__ import annotations

import uuid

from .admission import Admitted, AdmittedCalibration
from .cost import output_bytes
from .models import Kind, Run, Study


def jobs_page(session, owner: str, kind: Kind, offset: int = 0, limit: int = 200):
    """A page of ``owner``'s jobs of ``kind``, newest first, and how many there are in all."""
    from sqlmodel import func, select

    mine = (Study.owner == owner, Study.kind == kind)
    count = session.exec(select(func.count()).select_from(Study).where(*mine)).one()
    rows = session.exec(
        select(Study).where(*mine).order_by(Study.created_at.desc()).offset(offset).limit(limit)
    ).all()
    return rows, count


def study_rows(
    admitted: Admitted, owner: str, name: str | None, parent_id: uuid.UUID | None = None
) -> tuple[Study, list[Run]]:
    """The study row of an admitted study (its plan stored: what the worker runs) and a row
    per planned run; ``parent_id``: the calibration that queued it."""
    plan, costs = admitted
    study = Study(
        owner=owner,
        name=name,
        parent_id=parent_id,
        spec=plan.spec.to_dict(),
        plan=plan.to_dict(),
        n_runs=len(plan.runs),
        max_particles=plan.max_particles(),
        # the worst case its bounds allow, as admitted
        estimated_particle_steps=sum(c.particle_steps for c in costs),
    )
    runs = [
        Run(
            study_id=study.id,
            key=p.key,
            position=i,
            radius=p.radius,
            seed=p.seed,
            rule=p.label,
            particles=p.test.n_particles,
        )
        for i, p in enumerate(plan.runs)
    ]
    return study, runs


def calibration_row(admitted: AdmittedCalibration, owner: str, name: str | None) -> Study:
    """The job row of an admitted calibration (its normalised request in ``spec``; ``n_runs``
    the most parameter sets it runs)."""
    from engine.calibration import calibration_runs

    req = admitted.request
    return Study(
        kind=Kind.calibration,
        owner=owner,
        name=name,
        spec=req,
        n_runs=calibration_runs(req["runs"], req["waves"], req["wave_runs"]),
        max_particles=int(max(c.particles for c in admitted.costs)),
        estimated_particle_steps=sum(c.particle_steps for c in admitted.costs),
    )


def worst_case_bytes(admitted: AdmittedCalibration) -> float:
    """What a calibration (and the study it queues) can take on disk at worst [bytes]."""
    return output_bytes(admitted.costs) + output_bytes(admitted.then_costs)


def calibration_bytes(request: dict) -> float:
    """What a stored calibration (its normalised request) can take on disk at worst
    [bytes], the study it queues left out (a job of its own once queued)."""
    import engine
    from engine.calibration import LabTargets, calibration_runs
    from engine.calibration.calibrate import branch_stresses

    from .admission import calibration_costs, calibration_shear_tests

    test = engine.UniaxialTest.from_dict(request["test"])
    targets = LabTargets.from_dict(request["targets"])
    stresses = branch_stresses(test, targets)
    total = calibration_runs(request["runs"], request["waves"], request["wave_runs"])
    shear = calibration_shear_tests(test, targets, request.get("shear_test"))
    return output_bytes(calibration_costs(test, stresses, total, shear))
