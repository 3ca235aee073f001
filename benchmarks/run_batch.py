"""Run chosen runs of the reproduction's studies side by side on one many-core machine,
within a deadline (a lent machine, a cluster node's allocation, a batch job's time limit).

    python -m benchmarks.run_batch --cores 16 --deadline 540 --store /tmp/store \\
        c_eepa_cohesionless:ref-s1:4 d_eepa_cohesive:r5mm-linear-s1:1 ...

Each job is ``experiment:run-key:threads``. Jobs start in the order given, each as soon as
its threads fit in the free cores (a later, smaller job may fill a gap; none is ever started
twice). Every job is its own process, ``python -m benchmarks.reproduce --runs KEY`` with
``NUMBA_NUM_THREADS=threads`` and its own numba cache folder, so it stores its run as
``<store>/<scale>/<experiment>/<key>.h5`` exactly as the reproduction does (the engine's
results do not depend on the thread count). At the deadline [s after the start] every job
still running is killed, and its run is simply not stored (a stored run is written atomically,
see engine.io.store). ``--tar`` packs the store and the logs into one file at the end.

A run's numbers depend on the machine's floating-point code only through the compiler's
choice of instructions (numba compiles for the CPU it runs on), so a run stored on another
machine can differ from one stored here in the last bits, which a chaotic granular run grows
into a different (statistically equivalent) packing; the runs are compared as samples, never
bit for bit.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tarfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


@dataclass
class Job:
    experiment: str
    key: str
    threads: int
    proc: subprocess.Popen | None = None
    start: float = 0.0
    end: float = 0.0
    state: str = "waiting"

    @property
    def name(self) -> str:
        return f"{self.experiment}/{self.key}"


def parse_job(text: str) -> Job:
    parts = text.split(":")
    if len(parts) != 3 or not parts[2].isdigit() or int(parts[2]) < 1:
        raise SystemExit(f"job {text!r}: expected experiment:run-key:threads (threads >= 1)")
    return Job(parts[0], parts[1], int(parts[2]))


def reproduce_argv(job: Job, scale: str, store: Path) -> list[str]:
    """The command of one job: the reproduction, restricted to the job's run."""
    return [
        sys.executable,
        "-m",
        "benchmarks.reproduce",
        "--scale",
        scale,
        "--workers",
        "1",
        "--only",
        job.experiment,
        "--runs",
        job.key,
        "--store",
        str(store),
    ]


def launch(job: Job, argv: list[str], logs: Path) -> None:
    env = {
        **os.environ,
        "NUMBA_NUM_THREADS": str(job.threads),
        "PYTHONUNBUFFERED": "1",
        "DEMSCALE_CACHE_DIR": str(logs / "cache" / f"{job.experiment}-{job.key}"),
    }
    with open(logs / f"{job.experiment}-{job.key}.log", "w") as log:
        job.proc = subprocess.Popen(
            argv, cwd=ROOT, env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True
        )
    job.state = "running"


def run_batch(
    jobs: list[Job],
    cores: int,
    deadline: float,
    scale: str,
    store: Path,
    logs: Path,
    poll: float = 2.0,
    argv_of=reproduce_argv,
) -> list[Job]:
    """Run ``jobs`` on ``cores`` cores until all end or ``deadline`` seconds have passed;
    ``argv_of(job, scale, store)`` gives each job's command."""
    for job in jobs:
        if job.threads > cores:
            raise SystemExit(f"job {job.name}: {job.threads} threads > --cores {cores}")
    logs.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    while True:
        now = time.perf_counter() - t0
        for job in jobs:
            if job.state == "running" and job.proc.poll() is not None:
                job.end = now
                job.state = "done" if job.proc.returncode == 0 else f"exit {job.proc.returncode}"
                print(
                    f"[{now:6.0f} s] {job.name}: {job.state} after {job.end - job.start:.0f} s",
                    flush=True,
                )
        running = [j for j in jobs if j.state == "running"]
        if now >= deadline:
            for job in running:
                os.killpg(job.proc.pid, 9)
                job.proc.wait()
                job.state, job.end = "killed at the deadline", now
                print(f"[{now:6.0f} s] {job.name}: killed at the deadline", flush=True)
            break
        free = cores - sum(j.threads for j in running)
        for job in jobs:
            if job.state == "waiting" and job.threads <= free:
                launch(job, argv_of(job, scale, store), logs)
                job.start = now
                free -= job.threads
                print(f"[{now:6.0f} s] {job.name}: started on {job.threads} threads", flush=True)
        if not any(j.state in ("waiting", "running") for j in jobs):
            break
        time.sleep(poll)
    return jobs


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("jobs", nargs="+", help="experiment:run-key:threads")
    ap.add_argument("--cores", type=int, default=os.cpu_count())
    ap.add_argument("--deadline", type=float, required=True, help="seconds from the start")
    ap.add_argument("--scale", choices=("paper", "quick"), default="paper")
    ap.add_argument("--store", type=Path, required=True)
    ap.add_argument("--logs", type=Path, default=None, help="default: <store>/logs")
    ap.add_argument("--tar", type=Path, default=None, help="pack store and logs into this file")
    args = ap.parse_args(argv)
    jobs = [parse_job(t) for t in args.jobs]
    from benchmarks.experiments import EXPERIMENTS

    for job in jobs:
        if job.experiment not in EXPERIMENTS:
            raise SystemExit(
                f"job {job.name}: no experiment {job.experiment!r} "
                f"(one of {', '.join(EXPERIMENTS)})"
            )
    logs = args.logs or args.store / "logs"
    run_batch(jobs, args.cores, args.deadline, args.scale, args.store, logs)
    for job in jobs:
        print(
            f"{job.name}: {job.state}"
            + (f", {job.end - job.start:.0f} s" if job.state != "waiting" else "")
        )
    if args.tar is not None:
        with tarfile.open(args.tar, "w") as tar:
            if (args.store / args.scale).exists():
                tar.add(args.store / args.scale, arcname=args.scale)
            for f in sorted(logs.glob("*.log")):
                tar.add(f, arcname=f"logs/{f.name}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
