"""The checkpoints of a study's runs in flight, as the worker sees them: whether an attempt
moved one on (the poison rule of :func:`service.transitions.recover_stale`), and their
removal once the study has ended (a stored run's own checkpoint goes as soon as it is
stored: :func:`engine.run_study`)."""

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


def remove_all(directory: Path) -> None:
    """Delete a study's checkpoints (it has ended: nothing will resume them)."""
    shutil.rmtree(directory, ignore_errors=True)
