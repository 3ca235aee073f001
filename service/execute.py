"""Running one claimed study inside the worker: the engine in the calling thread, a
heartbeat thread beside it that records liveness and progress and learns of cancel
requests, and the final status change (succeeded, failed, cancelled, or back to queued on
shutdown)."""

from __future__ import annotations

import dataclasses
import logging
import os
import shutil
import threading
import time
import traceback
import uuid
from datetime import timedelta

from sqlmodel import Session

import engine
from engine.io.store import completed_runs
from engine.io.store import save_run as store_run
from engine.study.kinds import kind_of
from engine.study.plan import plan_runs
from engine.study.run import ADDED, Eta

from . import checkpoints, transitions
from .db import engine_for
from .h5store import NotOurs, write_results
from .jsonsafe import finite
from .models import Kind, Status, Study, utcnow
from .pools import run_executor
from .settings import Settings

log = logging.getLogger("demscale.worker")


class StudyExecution:
    """One attempt at a study by worker ``worker_id``; ``shutdown`` is set on SIGTERM."""

    def __init__(self, settings: Settings, worker_id: str, study: Study, shutdown: threading.Event):
        self.settings = settings
        self.worker_id = worker_id
        self.study_id: uuid.UUID = study.id
        self.spec_dict = study.spec
        self.plan_dict = study.plan
        self.shutdown = shutdown
        self.db = engine_for(settings)
        self.latest: engine.StudyProgress | None = None
        self.eta = Eta()  # this attempt's rate: its first report starts the clock
        self.seconds_left: float | None = None
        self.current_run: str | None = None
        self.cancel = False
        self.lost = False
        self.done = threading.Event()
        self.known_runs: set[str] = set()  # run keys with a row (added runs get one)
        self.plan: engine.StudyPlan | None = None
        self.test: engine.UniaxialTest | None = None

    # ------------------------------------------------------------------- heartbeat thread
    def beat(self) -> None:
        """Write heartbeat and progress; learn whether to stop."""
        p = self.latest
        with Session(self.db) as s:
            b = transitions.heartbeat(
                s,
                self.study_id,
                self.worker_id,
                progress=p.fraction if p else 0.0,
                run_index=p.run_index if p else None,
                current_run=p.run_key if p else None,
                current_stage=p.stage if p else None,
                finishes_at=None
                if self.seconds_left is None
                else utcnow() + timedelta(seconds=self.seconds_left),
            )
        if not b.owned and not self.lost:
            log.warning("study %s is no longer ours (heartbeat missed?): stopping", self.study_id)
            self.lost = True
        self.cancel = self.cancel or b.cancel_requested

    def _beat_loop(self) -> None:
        while not self.done.wait(self.settings.heartbeat_interval):
            try:
                self.beat()
            except Exception:  # a locked or briefly unavailable database: beat again later
                log.exception("heartbeat of study %s failed", self.study_id)

    # --------------------------------------------------------------------- engine thread
    def progress(self, p: engine.StudyProgress) -> bool:
        """The engine's progress callback: returns False to stop the study. The fraction
        shown never goes back (pool runs report as they come, out of step; a ``decide``
        study's added runs come out of the work it reserved for them, engine.StudyProgress);
        the time left is this attempt's rate applied to the work not done."""
        latest = self.latest
        if latest is not None and p.fraction < latest.fraction:
            p = dataclasses.replace(p, fraction=latest.fraction)
        self.latest = p
        self.seconds_left = self.eta(p.fraction)
        if p.stage == ADDED:  # a decide round's runs: their rows before any of them runs
            log.info("study %s: %s", self.study_id, p.message)
            try:
                self.ensure_row(p.run_key)
            except Exception:  # bookkeeping only: the run's own report tries again
                log.exception("study %s: could not add rows for %s", self.study_id, p.message)
            return not (self.cancel or self.lost or self.shutdown.is_set())
        if p.run_key != self.current_run:
            self.current_run = p.run_key
            try:  # an added run gets its row (and the study its run count) before it starts
                self.ensure_row(p.run_key)
            except Exception:  # bookkeeping only: on_run tries again
                log.exception("study %s: could not add a row for %s", self.study_id, p.run_key)
            try:
                with Session(self.db) as s:
                    transitions.run_started(s, self.study_id, p.run_key)
            except Exception:  # bookkeeping only: the study goes on
                log.exception("study %s: could not mark run %s", self.study_id, p.run_key)
            log.info("study %s: run %d/%d %s", self.study_id, p.run_index + 1, p.n_runs, p.run_key)
        if p.message.startswith(engine.RESUMED):
            log.info(
                "study %s: resuming run %s from its checkpoint (%s, %s)",
                self.study_id,
                p.run_key,
                p.stage,
                p.message,
            )
        return not (self.cancel or self.lost or self.shutdown.is_set())

    def ensure_row(self, key: str) -> None:
        """Give a run a ``decide`` study added a row, with the others of its round: the
        study's runs are replayed from the stored ones (engine.study.plan.plan_runs)."""
        if key in self.known_runs:
            return
        done, _ = completed_runs(self.plan, self.settings.runs_dir(self.study_id))
        planned = plan_runs(self.plan, done)[0]
        rows = [
            {
                "key": p.key,
                "radius": p.radius,
                "seed": p.seed,
                "rule": p.label,
                "particles": p.test.n_particles,
            }
            for p in planned
        ]
        with Session(self.db) as s:
            added = transitions.add_runs(s, self.study_id, rows)
        if added:
            log.info("study %s: %d runs added until decided", self.study_id, added)
        self.known_runs.update(p.key for p in planned)

    def on_run(self, key: str, outcome, added: list[dict] | None = None) -> None:
        """The engine reports a finished run: store it at once (atomically) so that a
        resumed study skips it, and mark its row. A failed coarse run is recorded with its
        error while the others go on; the verdicts name it. ``added``: for a run a
        ``decide`` round added, the additions of its round (engine.run_study's ``on_run``),
        stored with it so that a resumed study reads its rounds instead of replaying them."""
        store_run(self.settings.runs_dir(self.study_id) / f"{key}.h5", outcome, added=added)
        self.ensure_row(key)
        failed = isinstance(outcome, str)
        if not failed:
            self.store_snapshots(key, outcome)
        with Session(self.db) as s:
            transitions.run_finished(
                s,
                self.study_id,
                key,
                error=outcome if failed else None,
                steps=None if failed else int(outcome.scalars["steps"]),
                wall_time=None if failed else float(outcome.scalars["wall_time"]),
            )
        log.info("study %s: run %s %s", self.study_id, key, "failed" if failed else "stored")

    def store_snapshots(self, key: str, result) -> None:
        """ParaView files of the run's stage ends and the data of their PNG sections (drawn
        when first asked for: :func:`engine.io.vtkhdf.render_section`; drawing them here took
        two thirds of a small study's worker time), under ``<study>/snapshots/<key>/``
        (written into a temporary folder, then renamed)."""
        from engine.io.vtkhdf import save as save_snapshots

        if not kind_of(result).snapshots:  # a shear test's stages keep none
            return
        final = self.settings.snapshots_dir(self.study_id) / key
        tmp = final.with_name(f".{key}.{self.worker_id.replace(':', '-')}.tmp")
        shutil.rmtree(tmp, ignore_errors=True)
        try:
            save_snapshots(result, tmp, key, sections=False)
        except ValueError:  # a result without snapshots: nothing to show
            shutil.rmtree(tmp, ignore_errors=True)
            return
        shutil.rmtree(final, ignore_errors=True)
        os.replace(tmp, final)

    def stored_runs(self, plan: engine.StudyPlan, decided: list | None = None) -> dict:
        """Runs of this study stored by earlier attempts whose test is the planned one;
        ``decided``, where given, receives the rounds their added runs were stored with
        (engine.io.store.completed_runs), for ``engine.run_study(decided=...)``."""
        out, _ = completed_runs(plan, self.settings.runs_dir(self.study_id), decided)
        if out:
            log.info(
                "study %s: resuming with %d of %d runs stored",
                self.study_id,
                len(out),
                len(plan.runs),
            )
        return out

    def load_plan(self) -> engine.StudyPlan:
        """The plan stored with the study at submission (read back, not planned again); a
        study stored before plans were is planned from its spec."""
        if self.plan_dict is not None:
            return engine.StudyPlan.from_dict(self.plan_dict)
        return engine.plan(engine.StudySpec.from_dict(self.spec_dict))

    def remove_leftovers(self) -> None:
        """Delete the temporary results files of earlier attempts at this study (a worker
        killed while writing leaves its ``*.h5.tmp``): the study is this worker's now, and
        only its owner writes there."""
        d = self.settings.study_dir(self.study_id)
        for tmp in [*d.glob("*.h5.tmp"), *d.glob("runs/.*.tmp"), *d.glob("checkpoints/.*.tmp")]:
            log.warning("study %s: removing %s of an earlier attempt", self.study_id, tmp.name)
            tmp.unlink(missing_ok=True)
        for tmp in d.glob("snapshots/.*.tmp"):
            shutil.rmtree(tmp, ignore_errors=True)

    def run(self) -> Status | None:
        """Run the study to its end; returns the status it reached (None: no longer ours)."""
        log.info("study %s: started", self.study_id)
        self.remove_leftovers()
        t0 = time.perf_counter()
        beats = threading.Thread(target=self._beat_loop, name="heartbeat", daemon=True)
        beats.start()
        try:
            table = self.work()
        except engine.StopRequested:
            return self._stopped(time.perf_counter() - t0)
        except NotOurs:
            log.warning("study %s was taken over: results dropped", self.study_id)
            return None
        except Exception as e:
            self._finish_beats(beats)
            log.error("study %s failed:\n%s", self.study_id, traceback.format_exc())
            run_key = getattr(e, "run_key", None) or self.current_run
            with Session(self.db) as s:
                ok = transitions.fail(
                    s,
                    self.study_id,
                    self.worker_id,
                    f"{type(e).__name__}: {e}",
                    time.perf_counter() - t0,
                    run_key,
                )
            if ok:
                self.drop_checkpoints()
            return Status.failed if ok else None
        finally:
            self._finish_beats(beats)
        with Session(self.db) as s:
            ok = transitions.succeed(
                s, self.study_id, self.worker_id, time.perf_counter() - t0, table
            )
        if ok:
            self.drop_checkpoints()
        log.info("study %s: %s", self.study_id, "succeeded" if ok else "done, but not ours")
        return Status.succeeded if ok else None

    def work(self) -> list[dict]:
        """Run the study's runs not yet stored and write its results file; returns its
        result table (each run's steps and wall time)."""
        plan = self.plan = self.load_plan()
        self.known_runs.update(p.key for p in plan.runs)
        decided: list = []  # the rounds of the added runs stored by earlier attempts
        completed = self.stored_runs(plan, decided)
        with run_executor(self.settings, self.backend(plan)) as pool:
            # a run in flight keeps a checkpoint: after a crash it resumes where it was
            result = engine.run_study(
                plan,
                progress=self.progress,
                completed=completed,
                decided=decided,
                on_run=self.on_run,
                options=self.options(plan, pool),
            )
        write_results(
            self.settings.results_path(self.study_id),
            self.study_id,
            result,
            still_ours=self._still_ours,
        )
        return result.table

    def backend(self, plan: engine.StudyPlan) -> str:
        """The backend the study's runs take: the service's, or the first its reference's
        kind takes where it does not take the service's (as :meth:`options`)."""
        kind = kind_of(plan.spec.reference)
        backend = self.settings.backend
        if kind.backends is not None and backend not in kind.backends:
            backend = kind.backends[0]
        return backend

    def options(self, plan: engine.StudyPlan, pool) -> engine.RunOptions:
        """The study's run options (:meth:`Settings.run_options`), less what its reference's
        kind does not honour (engine.study.kinds: a shear study's without the per-run
        wall-time limit and on the CPU; the admission refused it where the service's backend
        is cuda): its runs are bounded by their stages' own bounds, as the admitted worst
        case counts."""
        options = self.settings.run_options(self.study_id, pool, self.channel(pool))
        kind = kind_of(plan.spec.reference)
        if not kind.wall_time_limit:
            options = dataclasses.replace(options, max_run_wall_time=None)
        if kind.backends is not None and options.backend not in (None, *kind.backends):
            options = dataclasses.replace(options, backend=kind.backends[0])
        return options

    def channel(self, pool) -> engine.FileChannel | None:
        """Runs in other processes or hosts report and hear a cancel through files in the
        job's folder (engine.FileChannel); None for runs in this process."""
        if pool is None:
            return None
        return engine.FileChannel(self.settings.study_dir(self.study_id) / "channel")

    def drop_checkpoints(self) -> None:
        """The study has ended: the checkpoints of runs it left in flight go."""
        checkpoints.remove_all(self.settings.checkpoints_dir(self.study_id))

    def _still_ours(self) -> bool:
        """A heartbeat right before the results file is renamed into place."""
        self.beat()
        return not self.lost

    def _finish_beats(self, beats: threading.Thread) -> None:
        self.done.set()
        beats.join()

    def _stopped(self, run_time: float) -> Status | None:
        with Session(self.db) as s:
            if self.lost:
                return None
            if self.cancel:
                log.info("study %s: cancelled", self.study_id)
                if not transitions.cancelled(s, self.study_id, self.worker_id, run_time):
                    return None
                self.drop_checkpoints()
                return Status.cancelled
            log.info("study %s: worker shutting down, back to the queue", self.study_id)
            return Status.queued if transitions.release(s, self.study_id, self.worker_id) else None


class CalibrationExecution(StudyExecution):
    """One attempt at a calibration (a job of kind ``calibration``): :func:`engine.calibrate`
    on the stored request, every run stored in the job's ``runs/`` folder as it finishes
    (a resumed attempt finds them; a run in flight starts again), a run row each, then the
    result (``calibration.json``, written atomically while the job is still ours) and, with
    ``then_study``, the study of the calibrated law queued as a job of its own."""

    def work(self) -> list[dict]:
        from engine.calibration import LabTargets

        req = self.spec_dict
        self.test = engine.UniaxialTest.from_dict(req["test"])
        targets = LabTargets.from_dict(req["targets"])
        shear_test = req.get("shear_test")  # the shear cell's fields, or None
        with run_executor(self.settings) as pool:
            cal = engine.calibrate(
                self.test,
                targets,
                {k: tuple(v) for k, v in req["parameters"].items()},
                runs=req["runs"],
                waves=req["waves"],
                wave_runs=req["wave_runs"],
                seed=req["seed"],
                resolution=req.get("resolution"),
                store=self.settings.runs_dir(self.study_id),
                progress=self.progress,
                on_run=self.on_point,
                options=self.settings.run_options(self.study_id, pool, self.channel(pool)),
                shear_test=shear_test,
                vary_seed=req.get("vary_seed", False),
            )
        summary = cal.to_summary()
        if req.get("then_study") is not None:
            summary["then_study"] = self.submit_study(req["then_study"], cal.law)
        self.write_summary(summary)
        return []

    def ensure_row(self, key: str) -> None:
        """A calibration's runs get their rows as they start (or, resumed, as they are found
        stored): they are chosen wave by wave, not planned."""
        if key in self.known_runs or self.test is None:
            return
        row = {
            "key": key,
            "radius": self.test.radius,
            "seed": self.test.seed,
            "rule": "calibration",
            "particles": self.test.n_particles,
        }
        with Session(self.db) as s:
            transitions.add_runs(s, self.study_id, [row])
        self.known_runs.add(key)

    def on_point(self, index: int, quantities) -> None:
        """engine.calibrate's on_run: the run (stored by the engine) is marked finished, or
        failed with its error (left out of the emulators; the calibration goes on)."""
        key = f"cal-{index:03d}"
        self.ensure_row(key)
        failed = isinstance(quantities, str)
        with Session(self.db) as s:
            transitions.run_finished(s, self.study_id, key, error=quantities if failed else None)

    def submit_study(self, then: dict, law) -> dict:
        """Queue the scaling study of the calibrated ``law`` (once: a resumed attempt finds
        the one it queued); returns its id, or the reason it was refused (the calibrated law
        may be one the study cannot take, e.g. too soft for its coarse radii)."""
        from dataclasses import replace

        from .admission import SpecRejected, admit_spec
        from .jobs import study_rows

        with Session(self.db) as s:
            have = transitions.child_of(s, self.study_id)
        if have is not None:
            return {"id": str(have)}
        data = {**then, "reference": replace(self.test, pair_law=law).to_dict()}
        try:
            admitted = admit_spec(data, self.settings)
        except SpecRejected as e:
            return {"id": None, "error": str(e)}
        with Session(self.db) as s:
            owner, name = transitions.owner_and_name(s, self.study_id)
            study, runs = study_rows(
                admitted, owner, f"{name or 'calibration'}: study", self.study_id
            )
            try:  # this calibration still holds its slot: the study may take one more
                transitions.submit(
                    s,
                    study,
                    runs,
                    self.settings.max_active + 1,
                    self.settings.max_active_per_token + 1,
                )
            except transitions.QueueFull as e:
                return {"id": None, "error": f"{e}: submit it again later"}
        log.info("calibration %s: study %s of the calibrated law queued", self.study_id, study.id)
        return {"id": str(study.id)}

    def write_summary(self, summary: dict) -> None:
        """``calibration.json`` of the job, written to a temporary file and renamed into
        place while the job is still this worker's."""
        import json

        path = self.settings.calibration_path(self.study_id)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        # strict JSON: a failed check run's NaN values as text (service.jsonsafe.finite)
        tmp.write_text(json.dumps(finite(summary), allow_nan=False, default=_plain_number))
        if not self._still_ours():
            tmp.unlink(missing_ok=True)
            raise NotOurs(self.study_id)
        os.replace(tmp, path)


def _plain_number(value):
    """numpy scalars as JSON numbers."""
    return value.item() if hasattr(value, "item") else str(value)


def execution_for(settings: Settings, worker_id: str, study: Study, shutdown) -> StudyExecution:
    """The execution of a claimed job of either kind."""
    cls = CalibrationExecution if study.kind == Kind.calibration else StudyExecution
    return cls(settings, worker_id, study, shutdown)
