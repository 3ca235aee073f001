"""The outlet series (benchmarks/outlet_series.py, outlet_report.py; issue 52 item 4): what
it holds across sizes, and how a seed's critical width is read from its runs."""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest

from benchmarks import outlet_report as R
from benchmarks import outlet_series as O


def test_the_discharge_series_holds_g_b_and_every_time_in_units_of_the_free_fall():
    tests = [O.flow_test(w, 1) for w in (8.0, 64.0)]
    for t in tests:
        b = t.outlet_width
        assert t.gravity * b == pytest.approx(O.G_FLOW)
        assert t.fill_height == pytest.approx(O.FILL_OVER_B * b)
        free_fall = math.sqrt(b / t.gravity)
        assert t.output_interval == pytest.approx(free_fall / O.SAMPLES_PER_FREE_FALL)
    # the arching series is the Jenike series' hopper at its own gravities
    a = O.test_of("arch", 50.0, 30.0, 2)
    assert a.gravity == 50.0 and a.outlet_width == pytest.approx(30.0 * O.D) and a.seed == 2


def test_a_seeds_critical_width_is_the_midpoint_of_its_bracket_and_censored_at_the_ends():
    c = R.critical_width({15.0: True, 17.0: True, 20.0: False, 23.0: False})
    assert (c["width"], c["below"], c["above"], c["monotone"]) == (18.5, 17.0, 20.0, True)
    # a width below the widest stop that went on: still bracketed, said not monotone
    c = R.critical_width({15.0: False, 17.0: True, 20.0: False})
    assert c["width"] == 18.5 and c["monotone"] is False
    assert R.critical_width({20.0: True, 23.0: True})["width"] is None
    assert R.critical_width({20.0: True, 23.0: True})["below"] == 23.0
    assert R.critical_width({20.0: False, 23.0: False})["width"] is None


def _failed(fraction, stopped=False):
    extra = {"before_failure": {"time": 0.2, "discharged_fraction": fraction, "stopped": stopped}}
    return SimpleNamespace(extra=extra)


def test_a_failed_run_counts_as_gone_on_only_past_half_its_fill_unstopped():
    assert R.went_on(_failed(0.95))
    assert not R.went_on(_failed(R.WENT_ON_FRACTION - 0.01))
    assert not R.went_on(_failed(0.95, stopped=True))
    assert not R.went_on(SimpleNamespace(extra={"before_failure": None}))


def _stored(numbers: dict):
    """A stand-in for ``outlet_series.stored``: (kind, width, seed) -> discharge number."""

    def stored(kind, x, width, seed, store=None):
        q = numbers.get((kind, width, seed))
        if q is None:
            return None
        extra = {"sink": "parked"} if kind == "sink" or width == 80.0 else {}
        scalars = {"discharge_number": q, "total_mass": 1.0}
        return SimpleNamespace(ok=True, scalars=scalars, extra=extra)

    return stored


def test_the_sink_check_decides_by_its_interval_and_gates_the_sink_runs(monkeypatch):
    """The rule of outlet_series' docstring: the 90 % t-interval of the mean paired relative
    difference within +-5 %: equivalent; wholly outside: different; else undecided. The
    slot's runs made with the sink join the discharge fit only when equivalent (the cone's,
    all made with it, are not gated)."""
    w = O.SINK_CHECK_WIDTH

    def check(drag, sink, wide=0.47):
        numbers = {("flow", w, s): q for s, q in enumerate(drag, 1)}
        numbers |= {("sink", w, s): q for s, q in enumerate(sink, 1)}
        numbers[("flow", 80.0, 1)] = wide
        monkeypatch.setattr(O, "stored", _stored(numbers))
        return R.sink_check(), R.flow_runs()

    c, runs = check([0.470, 0.472, 0.468], [0.471, 0.470, 0.469])
    assert c["verdict"] == "equivalent" and 80.0 in runs
    lo, hi = c["interval"]
    assert -0.05 <= lo < c["mean"] < hi <= 0.05
    c, runs = check([0.47, 0.47, 0.47], [0.52, 0.53, 0.525])  # +11 %, tight
    assert c["verdict"] == "different" and 80.0 not in runs and w in runs
    c, runs = check([0.47, 0.47, 0.47], [0.47, 0.52, 0.44])  # scattered: the interval is wide
    assert c["verdict"] == "undecided" and 80.0 not in runs
    assert any("80" in f and "sink" in f for f in R.flow_failures())
    c, runs = check([0.47, None, None], [0.47, None, None])  # one pair: no check
    assert c is None and 80.0 not in runs
    assert "not measured" in R.sink_lines()[0]


def test_where_two_stored_discharge_curves_part_is_a_fraction_of_the_fill():
    a = {"discharged_mass": [0.0, 0.3, 0.6, 0.9]}
    b = {"discharged_mass": [0.0, 0.3, 0.6, 0.8]}
    assert R._parted(a, b, 1.2) == pytest.approx(0.8 / 1.2)
    assert R._parted(a, a, 1.2) is None
    assert math.isnan(R._parted(a, None, 1.2))
