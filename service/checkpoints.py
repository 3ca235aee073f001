"""The checkpoints of a study's runs in flight, as the worker sees them: whether an attempt
moved one on (the poison rule of :func:`service.transitions.recover_stale`), the note of a
worker's death that shortens their interval, and their removal once the study has ended (a
stored run's own checkpoint goes as soon as it is stored: :func:`engine.run_study`)."""

from __future__ import annotations

import shutil
from datetime import datetime, timezone
from pathlib import Path


def advanced_since(directory: Path, since: datetime) -> bool:
    """Whether a checkpoint in ``directory`` was written at or after ``since`` (UTC; a naive
    time, as SQLite gives it back, is read as UTC)."""
    if since.tzinfo is None:
        since = since.replace(tzinfo=timezone.utc)
    t = since.timestamp()
    try:
        return any(p.stat().st_mtime >= t for p in directory.glob("*.ckpt"))
    except OSError:  # removed meanwhile
        return False


def note_crash(log: Path) -> None:
    """Note that a study's worker died (a line with the time, UTC): from then on its runs
    checkpoint every ``checkpoint_interval_after_crash`` (:meth:`Settings.run_options`), so
    that a worker killed again and again still moves it on."""
    log.parent.mkdir(parents=True, exist_ok=True)
    with open(log, "a") as f:
        f.write(datetime.now(timezone.utc).isoformat(timespec="seconds") + "\n")


def remove_all(directory: Path) -> None:
    """Delete a study's checkpoints (it has ended: nothing will resume them)."""
    shutil.rmtree(directory, ignore_errors=True)
