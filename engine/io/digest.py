"""A run's compact digest: what every verdict, table and curve fit of a size series reads,
bit-exact, in a small JSON file that lives in git, beside a full HDF5 file that does not
(issue 51 item 6: stored results that stop growing the clone).

A digest holds the test (its JSON form), the scalars, the verdict metrics' values
(:func:`engine.study.metrics.metric_values`, each float written as Python's shortest
round-tripping repr, so reading it back gives the same bits), the version of that metric
code (:data:`METRICS_VERSION`), the code and machine that made the run, and the sha256 and
size of the full file it was made from (curves, positions: regenerable by running the
test again, or kept in a data archive whose hash this names). A failed run's digest holds
its error text. Written atomically; read by :func:`read_digest`.
"""

from __future__ import annotations

import hashlib
import json
import os
import socket
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

#: Version of what a digest's ``metrics`` are computed by: raise it when
#: engine.study.metrics.metric_values (or a scalar it reads) changes meaning, so that a
#: report refuses digests of another version instead of mixing them.
METRICS_VERSION = 1
SCHEMA = "demscale-digest"


@dataclass
class Digest:
    """A run's digest (see the module docstring). ``outcome`` is ``"ok"`` or the error
    text; ``test`` the test's JSON and ``kind`` its class name; ``metrics`` name -> array."""

    kind: str
    test: dict
    outcome: str
    scalars: dict = field(default_factory=dict)
    metrics: dict = field(default_factory=dict)
    extra: dict = field(default_factory=dict)
    full_sha256: str | None = None
    full_bytes: int | None = None
    code: dict = field(default_factory=dict)
    metrics_version: int = METRICS_VERSION

    @property
    def ok(self) -> bool:
        return self.outcome == "ok"


def sha256_of(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def make_digest(outcome, test, full_path: Path | None = None, extra: dict | None = None) -> Digest:
    """The digest of ``outcome`` (a UniaxialResult or ShearResult, or an error text) of
    ``test``, naming the full file at ``full_path`` by hash. ``extra``: further numbers the
    report reads (JSON-able)."""
    from ..study.metrics import metric_values
    from ..uniaxial.checkpoint import this_code

    full = {}
    if full_path is not None and Path(full_path).exists():
        full = {
            "full_sha256": sha256_of(Path(full_path)),
            "full_bytes": Path(full_path).stat().st_size,
        }
    if isinstance(outcome, str):
        return Digest(type(test).__name__, test.to_dict(), outcome, extra=extra or {}, **full)
    metrics = {
        k: np.atleast_1d(np.asarray(v, dtype=float)).tolist()
        for k, v in metric_values(outcome).items()
    }
    return Digest(
        type(test).__name__,
        test.to_dict(),
        "ok",
        scalars={k: float(v) for k, v in outcome.scalars.items()},
        metrics=metrics,
        extra=extra or {},
        code=dict(this_code()),
        **full,
    )


def write_digest(path: Path, digest: Digest) -> Path:
    """Write ``digest`` to ``path`` (JSON) atomically."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    body = {"schema": SCHEMA, **digest.__dict__}
    tmp = path.with_name(f".{path.name}.{socket.gethostname()}.{os.getpid()}.tmp")
    tmp.write_text(json.dumps(body, indent=1, allow_nan=True) + "\n")
    tmp.replace(path)
    return path


def read_digest(path: Path) -> Digest:
    """The digest at ``path``; ValueError for another schema or metrics version."""
    body = json.loads(Path(path).read_text())
    if body.pop("schema", None) != SCHEMA:
        raise ValueError(f"{path}: not a {SCHEMA} file")
    d = Digest(**body)
    if d.metrics_version != METRICS_VERSION:
        raise ValueError(
            f"{path}: metrics version {d.metrics_version}, this code reads {METRICS_VERSION}"
        )
    d.metrics = {k: np.asarray(v, dtype=float) for k, v in d.metrics.items()}
    return d
