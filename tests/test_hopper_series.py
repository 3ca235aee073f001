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


def test_the_beverloo_figure_draws_points_fit_and_band(tmp_path):
    rng = np.random.default_rng(5)
    for w in S.FIRST_WIDTHS:
        for seed in (1, 2, 3):
            _write(tmp_path, w, seed, 0.60 * (w - 2.0) ** 1.5 * (1 + 0.01 * rng.standard_normal()))
    means = R.width_means(R.points(tmp_path))
    x, y, se = (np.array([m[k] for m in means]) for k in ("width", "mean", "se"))
    f = R.fit(x, y, se)
    grid = np.linspace(6.0, 40.0, 50)
    lo, hi = R.fit_band(f, x, y, se, grid)
    best = f["C"] * (grid - f["k"]) ** 1.5
    assert np.all(lo <= best) and np.all(best <= hi) and np.all(hi - lo > 0)
    # the band is narrowest where the widths are, and covers the curve the data came from
    assert np.all(lo <= 0.60 * (grid - 2.0) ** 1.5 * 1.01)
    fig = R.figure(tmp_path)
    ax, res = fig.axes[:2]
    labels = ax.get_legend_handles_labels()[1]
    assert labels[0] == "each run (15)" and any(lab.startswith("C (B/d - k)^1.5") for lab in labels)
    assert ax.get_xscale() == "log" and res.get_ylabel() == "against the fit [%]"
    path = R.write_figure(tmp_path / "fig" / "b.png", tmp_path)
    assert open(path, "rb").read(4) == b"\x89PNG"
    # two widths only: the points, and the lower panel says why there is no fit
    few = tmp_path / "few"
    for w in S.FIRST_WIDTHS[:2]:
        for seed in (1, 2):
            _write(few, w, seed, 0.60 * (w - 2.0) ** 1.5)
    (_, res) = R.figure(few).axes[:2]
    assert "no fit: 2 widths" in res.texts[0].get_text()
