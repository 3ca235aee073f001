"""The Beverloo report of the hopper series (benchmarks/hopper_report.py) on synthetic
digests: no simulation, a few milliseconds."""

from __future__ import annotations

import math

import numpy as np
import pytest

from benchmarks import hopper_report as R
from benchmarks import hopper_series as S
from engine.io.digest import Digest, write_digest


def _write(store, width, seed, y, y_se=None, rho_b=1200.0):
    """A digest of the series' run (width, seed) whose rate gives ``y`` exactly."""
    test = S.test_of(width, seed)
    d = 2.0 * test.radius
    scale = rho_b * math.sqrt(test.gravity) * d**1.5
    w = y * scale
    se = (y_se if y_se is not None else 0.01 * y) * scale * test.depth
    scalars = {
        "particles": float(test.n_particles),
        "discharge_rate_per_depth": w,
        "discharge_rate": w * test.depth,
        "discharge_rate_se": se,
        "bulk_density": rho_b,
    }
    extra = {"flow_mode": "mass", "cpu_seconds": 1.0, "wall_seconds": 2.0}
    write_digest(
        S.path_of(width, seed, store),
        Digest("HopperTest", test.to_dict(), "ok", scalars=scalars, extra=extra),
    )


def test_fit_recovers_c_and_k_of_exact_data():
    x = np.array([6.0, 8.0, 12.0, 18.0, 27.0])
    y = 0.6 * (x - 1.5) ** 1.5
    f = R.fit(x, y, 0.01 * y)
    assert f["C"] == pytest.approx(0.6, rel=1e-3)
    assert f["k"] == pytest.approx(1.5, abs=2e-3)
    assert f["C_interval"][0] <= 0.6 <= f["C_interval"][1]
    assert max(abs(r) for r in f["residual_sigma"]) < 0.2
    with pytest.raises(ValueError, match="three widths"):
        R.fit(x[:2], y[:2], y[:2])


def test_verdict_by_interval():
    assert R.verdict((0.58, 0.62), (0.55, 0.65)) == "within"
    assert R.verdict((0.70, 0.80), (0.55, 0.65)) == "outside"
    assert R.verdict((0.60, 0.70), (0.55, 0.65)) == "undecided"


def test_report_from_stored_digests(tmp_path):
    rng = np.random.default_rng(3)
    for w in S.FIRST_WIDTHS:
        for seed in (1, 2, 3):
            y = 0.60 * (w - 2.0) ** 1.5 * (1 + 0.01 * rng.standard_normal())
            _write(tmp_path, w, seed, y)
    means = R.width_means(R.points(tmp_path))
    assert [m["n"] for m in means] == [3] * 5
    # no width's error below the runs' own (1 % of y) over sqrt(3)
    assert all(m["se"] >= 0.0099 * m["mean"] / math.sqrt(3) for m in means)
    text = R.section(tmp_path)
    assert text.startswith(R.BEGIN) and text.endswith(R.END)
    assert "15 runs with a steady window of 18 planned" in text
    # C about 0.60 and k about 2.0: both inside the published ranges, decided
    row_c = next(line for line in text.splitlines() if line.startswith("| C |"))
    row_k = next(line for line in text.splitlines() if line.startswith("| k |"))
    assert "**within" in row_c and "**within" in row_k
    doc = tmp_path / "HOPPER.md"
    doc.write_text("# Hopper\n\n## Not measured / not done yet\n\n- x\n")
    R.write_report(doc, tmp_path)
    R.write_report(doc, tmp_path)  # the second time replaces the section
    body = doc.read_text()
    assert body.count(R.BEGIN) == 1 and body.index(R.END) < body.index("## Not measured")


def test_partial_series_leaves_the_fit_undecided(tmp_path):
    _write(tmp_path, 6.0, 1, 5.0)
    _write(tmp_path, 8.0, 1, 8.0)
    text = R.section(tmp_path)
    assert "2 runs with a steady window" in text
    assert "**Fit: not measured**" in text and "Verdict: undecided" in text
    # a digest of another test (a changed series) is not read
    other = S.path_of(12.0, 1, tmp_path)
    other.write_text(S.path_of(6.0, 1, tmp_path).read_text())
    assert S.stored(12.0, 1, tmp_path) is None
