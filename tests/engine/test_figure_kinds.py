"""Which plots a study has, asked of its kind of test in one place
(engine.io.figures.plot_kinds, TEST_PLOTS), and figures whose words never overlap: an
empty panel says one thing (a uniaxial study's yield-locus panel once drew two messages
on top of each other, issue 53). Made-up study data, no run."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

pytest.importorskip("matplotlib")
import engine
from engine.io.figures import (
    HOPPER_KINDS,
    KINDS,
    SHEAR_KINDS,
    TEST_PLOTS,
    UNIAXIAL_KINDS,
    discharge_rate,
    figure,
    kinds_of,
    plot_kinds,
)
from engine.study.report import StudyReport
from tests.engine.test_figures import study as uniaxial_study

TINY_SHEAR = {"type": "ShearTest", "pair_law": {"type": "BilinearAdhesive", "k1": 5e3}}


def shear_study() -> tuple[dict, list[dict], StudyReport]:
    """Two shear references and a coarse variant: yield points, fitted loci, pre-shear."""
    strain = np.linspace(0.0, 0.3, 40)
    runs, table = {}, []
    for key, rule, c in (
        ("ref-s1", "reference", 1.0e3),
        ("ref-s2", "reference", 1.2e3),
        ("r3mm-paper-s1", "paper", 0.8e3),
    ):
        runs[key] = {
            "label": key,
            "reference": rule == "reference",
            "stages": {
                "preshear": {"shear_strain": strain, "shear_stress": 4e3 * np.tanh(20 * strain)}
            },
            "points": [
                {"kind": "preshear", "sigma": 10e3, "tau": 4e3},
                {"kind": "failure", "sigma": 3e3, "tau": c + 0.5 * 3e3},
                {"kind": "failure", "sigma": 7e3, "tau": c + 0.5 * 7e3},
            ],
            "locus": {"cohesion": c, "slope": 0.5, "sigma_1": 20e3, "sigma_2": 5e3, "sigma_c": 3e3},
        }
        table.append(
            {
                "run": key,
                "rule": rule,
                "radius": 2.5e-3 if rule == "reference" else 3e-3,
                "wall_time": 10.0,
                "thickness_diameters": 10.0,
                "err_yield_locus": 0.05,
                "err_sigma_1": 0.02,
            }
        )
    return runs, table, StudyReport.from_dict({"tolerances": {"yield_locus": 0.1}, "verdicts": []})


def words(fig) -> list[tuple[str, object]]:
    """Every piece of words a person reads on ``fig`` (titles, axis labels, legends, notes;
    tick labels aside) with its box on the canvas."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    texts = [*fig.texts]
    if fig._suptitle is not None:
        texts.append(fig._suptitle)
    for legend in fig.legends:
        texts += [legend.get_title(), *legend.get_texts()]
    for ax in fig.axes:
        texts += [*ax.texts, ax.title, ax._left_title, ax._right_title]
        texts += [ax.xaxis.label, ax.yaxis.label]
        if ax.get_legend() is not None:
            texts += [ax.get_legend().get_title(), *ax.get_legend().get_texts()]
    unique = {id(t): t for t in texts}.values()  # the suptitle is among fig.texts too
    return [
        (t.get_text(), t.get_window_extent(renderer))
        for t in unique
        if t.get_visible() and t.get_text().strip()
    ]


@pytest.mark.parametrize("which", ["uniaxial", "shear"])
def test_no_figure_draws_words_over_words(which):
    data = uniaxial_study() if which == "uniaxial" else shear_study()
    for kind in KINDS:  # the study's own kinds and the other test's (a placeholder)
        placed = words(figure(kind, *data))
        assert placed, kind
        for (a, box_a), (b, box_b) in itertools.combinations(placed, 2):
            assert not box_a.overlaps(box_b), f"{which} {kind}: {a!r} over {b!r}"


def test_an_empty_panel_says_one_thing_and_names_the_study_s_plots():
    runs, table, report = uniaxial_study()
    (ax,) = figure("yield_locus", runs, table, report).axes
    (note,) = ax.texts
    assert "a uniaxial study" in note.get_text() and "stress_strain" in note.get_text()
    runs, table, report = shear_study()
    (ax,) = figure("unconfined", runs, table, report).axes
    (note,) = ax.texts
    assert "a shear study" in note.get_text() and "yield_locus" in note.get_text()


def test_a_study_s_plots_follow_its_kind_of_test():
    quick = engine.StudySpec(reference=engine.preset("quick"), coarse_radii=(3.125e-3,))
    assert plot_kinds(quick) == UNIAXIAL_KINDS
    assert plot_kinds(quick.to_dict()) == UNIAXIAL_KINDS  # the JSON form the service keeps
    no_ucs = {**quick.to_dict(), "controls": False}
    no_ucs["reference"] = {**no_ucs["reference"], "unconfined": False}
    assert plot_kinds(no_ucs) == (
        "stress_strain",
        "stress_porosity",
        "coordination",
        "error_vs_runtime",
    )
    shear = {"reference": TINY_SHEAR, "coarse_radii": [3e-3]}
    assert plot_kinds(shear) == SHEAR_KINDS
    assert not set(plot_kinds(shear)) & {"stress_strain", "unconfined"}
    assert not set(plot_kinds(quick)) & {"yield_locus", "preshear"}
    # the table of a stored study says the same
    assert kinds_of(uniaxial_study()[1]) == UNIAXIAL_KINDS
    assert kinds_of(shear_study()[1]) == ("yield_locus", "preshear", "error_vs_runtime")
    assert set(TEST_PLOTS) == {"UniaxialTest", "ShearTest", "HopperTest"}
    # a hopper study: its discharge rate and the verdicts' figures (docs/HOPPER.md)
    assert plot_kinds({"reference": {"type": "HopperTest"}, "controls": False}) == (
        "discharge",
        "error_vs_runtime",
    )
    with pytest.raises(ValueError, match="no plots"):
        plot_kinds({"reference": {"type": "Bogus"}})


def test_an_unbounded_interval_is_cut_at_1000_percent_with_an_arrow():
    """A two-seed interval to +1e6 % is drawn to +1000 % with an arrow (and read as
    unbounded in the legend), so that no tick reads +1e+06."""
    runs, table, report = uniaxial_study()
    data = report.to_dict()
    (m,) = [m for m in data["verdicts"][0]["metrics"] if m["metric"] == "loading_stiffness"]
    m["bias"]["interval"] = [-0.99, 1e4]  # -99 % to +1e6 %
    fig = figure("error_vs_runtime", runs, table, StudyReport.from_dict(data))
    ax = next(a for a in fig.axes if a.get_title().startswith("loading stiffness"))
    assert ax.get_ylim()[1] <= 1150.0
    arrows = [ln for ln in ax.get_lines() if ln.get_marker() == "^"]
    assert arrows and float(arrows[0].get_ydata()[0]) == pytest.approx(1000.0)
    fig.canvas.draw()
    ticks = [t.get_text() for t in ax.get_yticklabels() if t.get_text()]
    assert ticks and not any("e+" in t for t in ticks), ticks
    legend = [t.get_text() for t in fig.legends[0].get_texts()]
    assert any("unbounded (too few seeds)" in t for t in legend), legend


def test_the_discharge_plot_draws_each_groups_rate_against_time():
    """Made-up discharges: 1 kg at 2 kg/s from t = 0.1 s (two reference seeds) and at 1 kg/s
    (a coarse run), sampled every 10 ms: the rate curves' plateaus and the steady rates
    (dotted) are those rates."""
    t = np.arange(0.0, 1.3, 0.01)
    runs, table = {}, []
    for key, rate, ref in (
        ("ref-s1", 2.0, True),
        ("ref-s2", 2.0, True),
        ("r3mm-paper-s1", 1.0, False),
    ):
        m = np.clip(rate * (t - 0.1), 0.0, 1.0)
        runs[key] = {
            "label": key,
            "reference": ref,
            "stages": {"discharge": {"time": t, "discharged_mass": m}},
        }
        table.append(
            {
                "run": key,
                "radius": 2.5e-3 if ref else 3e-3,
                "rule": "reference" if ref else "paper",
                "discharge_rate": rate,
                "err_discharge_number": 0.0,
            }
        )
    tt, r = discharge_rate(t, runs["ref-s1"]["stages"]["discharge"]["discharged_mass"])
    assert np.array_equal(tt, t) and np.allclose(r[(t > 0.2) & (t < 0.5)], 2.0)
    assert np.allclose(r[t > 0.75], 0.0)  # emptied at 0.6 s
    assert kinds_of(table) == HOPPER_KINDS[:2]  # no controls
    (ax,) = figure("discharge", runs, table).axes
    solid = [ln for ln in ax.get_lines() if ln.get_linestyle() == "-"]
    dotted = sorted(float(ln.get_ydata()[0]) for ln in ax.get_lines() if ln.get_linestyle() == ":")
    assert dotted == [1.0, 2.0]
    assert sorted(round(float(np.max(ln.get_ydata())), 6) for ln in solid) == [1.0, 2.0]
    labels = ax.get_legend_handles_labels()[1]
    assert labels == ["reference (mean of 2 seeds ± 1 sd)", "R = 3 mm, paper"]
    assert "mass discharge rate [kg/s]" in ax.get_ylabel() and not ax.texts
