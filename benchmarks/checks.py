"""Target checks shared by the benchmarks, and another engine version to compare with."""

from __future__ import annotations

import contextlib
import json
import os
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


@contextlib.contextmanager
def worktree(rev: str) -> Iterator[Path]:
    """The repository at git revision ``rev``, checked out into a temporary git worktree
    (removed afterwards): a baseline engine to run in its own process beside this one."""
    with tempfile.TemporaryDirectory() as tmp:
        tree = Path(tmp) / "baseline"
        subprocess.run(
            ["git", "-C", str(ROOT), "worktree", "add", "--detach", str(tree), rev],
            check=True,
            capture_output=True,
        )
        try:
            yield tree
        finally:
            subprocess.run(
                ["git", "-C", str(ROOT), "worktree", "remove", "--force", str(tree)],
                check=False,
                capture_output=True,
            )


def report(checks: list[tuple[str, bool]]) -> int:
    """Print PASS/FAIL per target; the exit status is 0 when every target is met."""
    print()
    for what, ok in checks:
        print(f"{'PASS' if ok else 'FAIL'}  {what}")
    return 0 if all(ok for _, ok in checks) else 1


def run_child(tree: Path, code: str, args=(), **env) -> object:
    """Run ``code`` with the engine of ``tree`` in a fresh Python process (``env`` added to
    the environment, e.g. its own ``DEMSCALE_CACHE_DIR``) and return the JSON value its last
    line prints."""
    out = subprocess.run(
        [sys.executable, "-c", code, *map(str, args)],
        cwd=tree,
        env={**os.environ, "PYTHONPATH": str(tree), **{k: str(v) for k, v in env.items()}},
        check=True,
        capture_output=True,
        text=True,
    )
    return json.loads(out.stdout.strip().splitlines()[-1])
