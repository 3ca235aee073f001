"""Target checks shared by the benchmarks, and another engine version to compare with."""

from __future__ import annotations

import contextlib
import json
import os
import subprocess
import sys
import tempfile
import time
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


def publish(path: Path, text: str) -> None:
    """Write a benchmark's report ``text`` to ``path`` and print it."""
    path.write_text(text)
    print(text)


def write_marked(doc: Path, begin: str, end: str, text: str, title: str) -> None:
    """Put ``text`` between the markers ``begin`` and ``end`` of the Markdown file ``doc``,
    replacing what stood between them; a file without both markers gets the marked block
    appended (a new or empty one under the heading ``# <title>``)."""
    block = f"{begin}\n{text}{end}"
    old = doc.read_text() if doc.exists() else ""
    if begin in old and end in old:
        a, b = old.index(begin), old.index(end) + len(end)
        doc.write_text(old[:a] + block + old[b:])
    else:
        doc.write_text(old + ("\n" if old else f"# {title}\n\n") + block + "\n")


def save_figure(fig, path: Path, dpi: int) -> None:
    """Lay out the matplotlib figure ``fig``, write it to ``path`` (its folder made) at
    ``dpi`` and close it."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)


class Ticker:
    """A run's progress callback that prints ``line(progress, seconds since it started)``
    at most once every ``every`` seconds [s] of wall time."""

    def __init__(self, line, every: float = 60.0):
        self.line, self.every = line, every
        self.t0 = self.last = time.perf_counter()

    def __call__(self, pr) -> None:
        now = time.perf_counter()
        if now - self.last >= self.every:
            self.last = now
            print(self.line(pr, now - self.t0), flush=True)


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


def commit_stored(path: Path, message: str) -> None:
    """Commit one stored result file at ``path`` alone (``git commit -- path``), waiting a
    little for another engineer's commit that holds the index."""
    rel = str(Path(path).resolve().relative_to(ROOT))
    for _ in range(30):
        if not (ROOT / ".git" / "index.lock").exists():
            break
        time.sleep(2)
    subprocess.call(["git", "add", rel], cwd=ROOT)
    subprocess.call(["git", "commit", "-q", "-m", message, "--", rel], cwd=ROOT)


def run_and_store(test, path: Path, label: str, commit: bool, interval: float = 300.0) -> str:
    """Run the uniaxial ``test`` on one engine thread with a checkpoint beside ``path``
    (``.checkpoints/<stem>.ckpt``, written every ``interval`` s of wall time and after the
    fill, so a run cut off resumes bit for bit), store its outcome at ``path`` (an error as
    its text, as the studies store it), drop the checkpoint and, with ``commit``, commit
    the file as "<label>: <stem> stored (<wall time> s)". Returns a line for the log."""
    import numba

    import engine
    from engine.io.store import save_run
    from engine.uniaxial.checkpoint import Checkpoint

    numba.set_num_threads(1)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    ckpt = Checkpoint(path.parent / ".checkpoints" / f"{path.stem}.ckpt", interval)
    t0 = time.perf_counter()
    try:
        outcome = engine.run_uniaxial(test, checkpoint=ckpt)
    except Exception as e:
        outcome = f"{type(e).__name__}: {e}"
    save_run(path, outcome, keep_particles=False)
    ckpt.remove()
    took = time.perf_counter() - t0
    if commit:
        commit_stored(path, f"{label}: {path.stem} stored ({took:.0f} s)")
    resumed = "" if ckpt.resumed_steps is None else f", resumed at step {ckpt.resumed_steps}"
    return f"{path.stem}: {took:.0f} s{resumed}"
