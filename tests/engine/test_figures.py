"""The study figures read right (issue 42): signed errors on a symmetric-log axis whose
ticks are numbers, a resolution plot for a study whose controls are too few for a line, an
sd band that stops at zero stress, units in every title. Made-up study data (what
engine.io.figures.study_plot_data gives), no run."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("matplotlib")
from engine.io.figures import KINDS, UNIAXIAL_KINDS, figure, has_controls, save_all
from engine.study.report import StudyReport

TOL = {"density": 0.03, "loading_stiffness": 0.15, "strength": 0.15}


def metric(name: str, err: float, lo: float, hi: float) -> dict:
    return {"metric": name, "signed_error": err, "bias": {"error": err, "interval": [lo, hi]}}


def study(controls: bool = True) -> tuple[dict, list[dict], StudyReport]:
    """Two references, a coarse variant 26 % weak in strength, and (with ``controls``) its
    resolution control of one seed: too few for a resolution curve."""
    t = np.linspace(0.0, 1.0, 50)
    runs, table = {}, []
    for key, rule, peak, wall in (
        ("ref-s1", "reference", 10e3, 40.0),
        ("ref-s2", "reference", 2e3, 44.0),  # a wide spread: the mean - sd is below zero
        ("r5mm-paper-s1", "paper", 5e3, 4.0),
        *((("ctl-r5mm-s1", "control", 6e3, 3.5),) if controls else ()),
    ):
        stress = peak * np.sin(np.pi * t)
        runs[key] = {
            "label": key,
            "reference": rule == "reference",
            "stages": {"unconfined": {"strain": 0.1 * t, "stress_top": stress}},
        }
        table.append(
            {
                "run": key,
                "rule": rule,
                "radius": 2.5e-3 if rule == "reference" else 5e-3,
                "wall_time": wall,
                "thickness_diameters": 10.0 if rule == "reference" else 5.0,
                "err_density": 0.01,
                "err_loading_stiffness": 0.1,
                "err_strength": 0.26,
                "unconfined_strength": peak,
            }
        )
    report = {
        "tolerances": TOL,
        "noise_floor": {"density": 0.01, "loading_stiffness": 0.05, "strength": 0.1},
        "verdicts": [
            {
                "radius": 5e-3,
                "rule": "paper",
                "metrics": [
                    metric("density", 0.012, -0.01, 0.03),
                    metric("loading_stiffness", 0.08, -0.2, 0.5),
                    metric("strength", -0.26, -0.9, 3.0),
                ],
            }
        ],
        "resolution": [
            {
                "radius": 5e-3,
                "rule": "control",
                "what": "resolution",
                "diameters_across": 5.0,
                "metrics": [metric("strength", -0.18, -0.18, -0.18)],
            }
        ]
        if controls
        else [],
        "rule_errors": [],
        "resolution_curve": {"metrics": {}, "confidence": 0.95},
    }
    return runs, table, StudyReport.from_dict(report)


def test_errors_are_signed_on_an_axis_that_reads():
    fig = figure("error_vs_runtime", *study())
    panels = {ax.get_title(): ax for ax in fig.axes}
    ax = panels["unconfined strength [%]"]
    assert ax.get_yscale() == "symlog"
    # the variant's -26 % is drawn at -26, its interval as far as +300 %
    ys = [float(y) for line in ax.get_lines() for y in np.atleast_1d(line.get_ydata())]
    assert -26.0 in [round(y, 6) for y in ys]
    fig.canvas.draw()
    labels = [t.get_text() for t in ax.get_yticklabels() if t.get_text()]
    assert len(labels) >= 4 and any(t.startswith("-") for t in labels), labels
    xlabels = [t.get_text() for t in ax.get_xticklabels() if t.get_text()]
    assert len(xlabels) >= 3 and all("^" not in t for t in xlabels), xlabels  # plain seconds
    assert all("[%]" in a.get_title() for a in fig.axes)


def test_a_study_with_controls_too_few_for_a_line_shows_them():
    runs, table, report = study()
    assert has_controls(table)
    fig = figure("resolution", runs, table, report)
    text = fig._suptitle.get_text()
    assert "no line to the bulk" in text and "no resolution controls" not in text
    ax = next(a for a in fig.axes if a.get_title().startswith("unconfined strength"))
    ys = [round(float(y), 6) for line in ax.get_lines() for y in np.atleast_1d(line.get_ydata())]
    assert -18.0 in ys  # the control's own error, at its d / L
    # without controls, the plot says so, and save_all leaves it out
    runs, table, report = study(controls=False)
    assert (
        "no resolution controls"
        in figure("resolution", runs, table, report).axes[0].texts[0].get_text()
    )


def test_the_sd_band_stops_at_zero_stress(tmp_path):
    fig = figure("unconfined", *study()[:2])
    (ax,) = fig.axes
    bands = [c for c in ax.collections if c.get_paths()]
    assert bands
    lowest = min(float(p.vertices[:, 1].min()) for c in bands for p in c.get_paths())
    assert lowest >= 0.0  # kPa: the mean of 10 and 2 kPa peaks less its sd is below zero
    written = save_all(tmp_path, *study())
    assert {p.stem for p in written} == set(UNIAXIAL_KINDS)
    assert all(any(u in t for u in ("[kPa]", "[%]", "[-]", "[s]")) for t in KINDS.values()), (
        "units in every title"
    )


def test_the_unconfined_plot_draws_the_curve_the_strength_is_read_from():
    # the default protocol reads a strength from the interior's virial stress: drawn where
    # every run has it; a run without it (the seed's protocol) makes it the top platen's
    from engine.io.figures import _unconfined_stress

    def run(interior):
        c = {"strain": [0.0, 0.01], "stress_top": [0.0, 1.0]}
        if interior is not None:
            c["stress_interior"] = interior
        return {"stages": {"unconfined": c}}

    assert _unconfined_stress({"a": run([0.0, 2.0]), "b": run([1.0, 3.0])}) == "stress_interior"
    assert _unconfined_stress({"a": run([0.0, 2.0]), "b": run(None)}) == "stress_top"
    assert _unconfined_stress({"a": run([0.0, float("nan")])}) == "stress_top"


def test_a_shear_calibration_draws_its_yield_loci_and_its_scalar_targets():
    """A calibration to a shear tester's data (the stored twin benchmark): a yield-locus
    panel with the laboratory points and the check run's loci, and the pre-shear stresses
    and bulk densities over their laboratory values; no empty panel."""
    import json
    from pathlib import Path

    from engine.io.figures import calibration_figure

    stored = Path(__file__).resolve().parents[2] / "benchmarks" / "results"
    summary = json.loads((stored / "calibration_shear_tiny" / "result.json").read_text())
    fig = calibration_figure(summary)
    locus, other = fig.axes
    assert locus.get_title().startswith("yield loci")
    assert other.get_title().startswith("other targets")
    lab = [c for c in locus.containers if c.get_label().startswith("laboratory")]
    assert [c.get_label() for c in lab] == [
        "laboratory, pre-shear 10 kPa (1 sd)",
        "laboratory, pre-shear 20 kPa (1 sd)",
    ]
    assert len(locus.get_lines()) >= 2  # a fitted locus per pre-shear stress
    ticks = [t.get_text() for t in other.get_xticklabels()]
    assert len(ticks) == 4 and ticks[0].startswith("tau_pre\n@10000Pa")
