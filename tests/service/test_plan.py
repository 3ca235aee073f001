"""A study is planned once: at submission (engine.plan), stored with its row, and run as
stored by the worker, which plans nothing again."""

from __future__ import annotations

import uuid

from sqlmodel import Session

import engine
from service.db import engine_for
from service.models import Status, Study
from service.worker import Worker

from .conftest import TINIEST


def _counting(monkeypatch) -> list:
    calls = []
    real = engine.plan

    def counted(spec):
        calls.append(spec)
        return real(spec)

    monkeypatch.setattr(engine, "plan", counted)
    return calls


def test_a_submission_plans_once_and_the_worker_runs_the_stored_plan(client, settings, monkeypatch):
    calls = _counting(monkeypatch)
    r = client.post("/studies", json=TINIEST)
    assert r.status_code == 202, r.text
    assert len(calls) == 1  # admission, row, runs: one plan
    sid = r.json()["id"]
    with Session(engine_for(settings)) as s:
        row = s.get(Study, uuid.UUID(sid))
        stored = engine.StudyPlan.from_dict(row.plan)
    assert [p.key for p in stored.runs] == ["ref-s1", "r3.1mm-paper-s1"]
    # read back, the stored plan is the plan: the same records, nothing planned again
    assert stored == engine.study.plan.plan(calls[0])
    calls.clear()
    Worker(settings, once=True).run()
    assert calls == []  # the worker read the plan back: it planned nothing
    body = client.get(f"/studies/{sid}").json()
    assert body["status"] == Status.succeeded.value, body


def test_a_study_stored_before_plans_were_is_planned_by_its_worker(client, settings, monkeypatch):
    r = client.post("/studies", json=TINIEST)
    sid = uuid.UUID(r.json()["id"])
    with Session(engine_for(settings)) as s:  # as a store from before the plan column
        row = s.get(Study, sid)
        row.plan = None
        s.add(row)
        s.commit()
    calls = _counting(monkeypatch)
    Worker(settings, once=True).run()
    assert len(calls) == 1
    assert client.get(f"/studies/{sid}").json()["status"] == Status.succeeded.value
