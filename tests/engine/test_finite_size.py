"""The finite-size control of experiment (b) (benchmarks/finite_size.py, issue 19 point 6)
is the reference shrunk in every length of the cell to the coarse 5 mm bed in diameters.
Built, not run."""

from __future__ import annotations

import pytest

from benchmarks.experiments import experiments
from benchmarks.finite_size import COARSE_RADIUS, control_test, reference_test
from engine.study.plan import reference_test as study_reference


@pytest.fixture(scope="module")
def tests_():
    spec = experiments("paper")["b_cohesive"]
    ref = study_reference(spec)  # as the study's plan runs it, with the study's margin
    b2 = next(r for r in spec.rules if r.name == "b2")
    coarse = b2.apply(ref, COARSE_RADIUS, ref.resolved_dt())  # as engine.plan builds it
    return ref, control_test(2, reference_test()), coarse


def test_control_is_the_reference_halved(tests_):
    ref, ctrl, _ = tests_
    assert ref.radius / COARSE_RADIUS == pytest.approx(0.5)
    for c, r in zip(ctrl.cell, ref.cell):
        assert c == pytest.approx(0.5 * r)
    assert ctrl.cell == pytest.approx((0.025, 0.075, 0.15))
    assert ctrl.platen_speed == pytest.approx(0.5 * ref.platen_speed)
    assert ctrl.margin == pytest.approx(0.5 * ref.margin)
    assert ctrl.pour_height == pytest.approx(0.5 * ref.pour_height)
    # the reference's particles, law, gravity-free fields and time step, unscaled
    assert ctrl.radius == ref.radius
    assert ctrl.pair_law == ref.pair_law
    assert ctrl.pair_law.f0 == -0.8 and ctrl.pair_law.k1 == 5e3 and ctrl.pair_law.k2 == 2.5e4
    assert ctrl.dt == ref.dt
    assert ctrl.seed == 2


def test_control_has_the_coarse_bed_in_diameters(tests_):
    ref, ctrl, coarse = tests_
    assert coarse.radius == COARSE_RADIUS
    assert ctrl.thickness_diameters == pytest.approx(5.0)
    assert ctrl.thickness_diameters == pytest.approx(coarse.thickness_diameters)
    d_ctrl, d_coarse = 2 * ctrl.radius, 2 * coarse.radius
    for c, k in zip(ctrl.cell, coarse.cell):
        assert c / d_ctrl == pytest.approx(k / d_coarse)  # 5 x 15 x 30 diameters
    assert ctrl.margin / d_ctrl == pytest.approx(coarse.margin / d_coarse)
    assert abs(ctrl.n_particles / coarse.n_particles - 1) < 0.03
    assert ref.n_particles / ctrl.n_particles == pytest.approx(8, rel=0.01)
    # the same strain rate (speed / cell height) as the reference and the coarse run
    assert ctrl.platen_speed / ctrl.cell[2] == pytest.approx(ref.platen_speed / ref.cell[2])
    assert ctrl.platen_speed / ctrl.cell[2] == pytest.approx(coarse.platen_speed / coarse.cell[2])
