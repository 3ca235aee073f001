"""The report's claims (benchmarks/report.py) on small synthetic tables where the right word
is known: a wrong mapping from verdicts to agrees / differs / undecided fails here."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from benchmarks import report
from engine.study.report import MetricVerdict, StudyReport

R = 2.5e-3


def _m(name, signed, verdict):
    return {
        "metric": name,
        "signed_error": signed,
        "error": abs(signed),
        "verdict": verdict,
        "level_error": signed,
        "interval": [signed - 0.05, signed + 0.05],
        "differs_error": signed,
        "differs_interval": [signed - 0.08, signed + 0.08],
        # the two-sided interval of the signed error: a bias where it excludes zero
        "bias": {
            "direction": "high" if signed > 0.05 else "low" if signed < -0.05 else None,
            "error": signed,
            "interval": [signed - 0.05, signed + 0.05],
        },
    }


def _res(verdicts, radii=(2 * R,), runs=None, groups=()):
    spec = SimpleNamespace(coarse_radii=radii, reference=SimpleNamespace(radius=R, dt=1e-5))
    return SimpleNamespace(
        spec=spec,
        report=StudyReport.from_dict({"verdicts": verdicts}),
        runs=runs or {},
        groups=list(groups),
    )


def _v(radius, rule, verdict, *metrics):
    return {"radius": radius, "rule": rule, "verdict": verdict, "metrics": list(metrics)}


def _word(text):
    return text.split("**")[1]


@pytest.mark.parametrize(
    ("signed", "verdict", "word"),
    [
        (-0.45, "differs", "agrees"),  # softer beyond noise
        (-0.45, "undecided", "undecided"),  # softer, not beyond noise
        (0.30, "differs", "differs"),  # stiffer: the claim is reversed
        (-0.05, "equivalent", "differs"),  # no softening
    ],
)
def test_claim_a(signed, verdict, word):
    res = _res([_v(2 * R, "unscaled", verdict, _m("loading_stiffness", signed, verdict))])
    assert _word(report.claim_a(res)) == word


def test_claim_a_without_runs_is_undecided():
    assert "undecided" in report.claim_a(_res([]))


@pytest.mark.parametrize(
    ("verdicts", "word"),
    [
        (["equivalent"] * 4, "agrees"),
        (["equivalent", "differs", "equivalent", "undecided"], "differs"),
        (["equivalent", "undecided", "equivalent", "equivalent"], "undecided"),
    ],
)
def test_claim_b(verdicts, word):
    names = ("density", "loading_stiffness", "unloading_stiffness", "coordination")
    res = _res([_v(2 * R, "linear", "x", *[_m(n, 0.01, v) for n, v in zip(names, verdicts)])])
    assert _word(report.claim_b(res)) == word


@pytest.mark.parametrize(
    ("b1", "b2", "b3", "word"),
    [
        ((-0.4, "differs"), (0.02, "equivalent"), (0.4, "differs"), "agrees"),
        ((-0.4, "differs"), (-0.3, "differs"), (0.4, "differs"), "differs"),  # b = 2 off
        ((0.1, "undecided"), (0.02, "equivalent"), (0.4, "differs"), "differs"),  # b = 1 over
        ((0.04, "undecided"), (0.02, "equivalent"), (0.4, "differs"), "undecided"),  # not shown
        ((-0.4, "differs"), (0.02, "undecided"), (0.4, "differs"), "undecided"),
        ((-0.4, "undecided"), (0.02, "equivalent"), (0.4, "differs"), "undecided"),
    ],
)
def test_claim_c(b1, b2, b3, word):
    vs = [
        _v(2 * R, rule, "x", _m("strength", *x)) for rule, x in (("b1", b1), ("b2", b2), ("b3", b3))
    ]
    lines = report.claim_c(_res(vs))
    assert _word(lines[0]) == word


def _run(rule, radius, steps, control=False):
    name = rule
    rule = None if rule is None else SimpleNamespace(name=rule)
    return SimpleNamespace(
        rule=rule,
        radius=radius,
        control=control,
        is_reference=name is None and not control,
        result=SimpleNamespace(scalars={"particle_steps": steps}),
    )


def test_the_particle_steps_ratio_leaves_the_controls_out():
    # a resolution control has no rule either, and costs what a coarse run does: counted
    # as a reference it made the paper rule's particle-steps ratio 1.7x instead of 3.2x
    runs = {
        "ref-s1": _run(None, R, 1e10),
        "ctl-r5mm-s1": _run(None, 2 * R, 1e9, control=True),
        "r5mm-b2-s1": _run("b2", 2 * R, 1e9),
    }
    res = _res([], runs=runs)
    assert report.particle_steps_ratio(res, "b2", 2 * R) == pytest.approx(10.0)


@pytest.mark.parametrize(("k", "word"), [(3.5, "agrees"), (2.9, "differs"), (4.5, "differs")])
def test_claim_d_reads_the_fitted_particle_steps_ratio(k, word):
    # particle-steps falling as s^k: at s = 1.875, 1.875^3.5 = 9.0 agrees within 25 %
    s = (1.5, 2.0)
    runs = {"ref-s1": _run(None, R, 1e10)}
    for x in s:
        runs[f"r{x}"] = _run("b2", x * R, 1e10 / x**k)
    res = _res([], radii=tuple(x * R for x in s), runs=runs)
    text = report.claim_d(res)
    assert _word(text) == word
    assert f"{1.875**k:.1f}x" in text


@pytest.mark.parametrize(
    ("sim", "lin", "k_signed", "e", "f"),
    [
        ("equivalent", "differs", 0.25, "agrees", "agrees"),
        ("differs", "equivalent", 0.0, "differs", "differs"),
        ("undecided", "differs", -0.2, "undecided", "undecided"),  # softer: not the claim
        ("equivalent", "undecided", 0.25, "agrees", "undecided"),
    ],
)
def test_claims_e_and_f(sim, lin, k_signed, e, f):
    vs = [
        _v(2 * R, "similarity", sim, _m("loading_stiffness", 0.0, sim)),
        _v(2 * R, "linear", lin, _m("loading_stiffness", k_signed, lin)),
    ]
    line = report.claim_eepa(_res(vs))[0]
    words = line.split("**")
    assert words[1] == e and words[3] == f


def _judged(verdict, interval, bias=None, differs=None, level=None, tolerance=0.15, **kw):
    """A metric as engine.study.judge.judge_metric makes it, for the words of a cell."""
    e = sum(interval) / 2
    return {
        "metric": "strength",
        "tolerance": tolerance,
        "verdict": verdict,
        "signed_error": e,
        "level_error": e,
        "interval": list(interval),
        "level": level,
        "differs_error": e,
        "differs_interval": list(differs or interval),
        "alpha_differs": 0.005,
        "seeds": 8,
        "reference_seeds": 3,
        "bias": {"direction": bias, "error": e, "interval": list(interval)},
        **kw,
    }


def _text(m: dict) -> str:
    """The words of the cell of judged metric ``m`` (its record, as a report holds it)."""
    return report.judged_text(MetricVerdict.from_dict(m))


def test_a_cell_says_no_more_than_its_verdict_decided():
    # equivalent, and an interval that excludes 0: within the tolerance and biased
    m = _judged("equivalent", (-0.113, -0.095), bias="low")
    assert _text(m) == "-10.4 [-11.3, -9.5] % (equivalent within 15 %, biased low)"
    # equivalent with no bias: the bare verdict
    assert _text(_judged("equivalent", (-0.05, 0.04))).endswith("(equivalent)")
    # a curve whose worst level excludes 0 while its mean over levels does not
    m = _judged("equivalent", (-0.003, -0.001), level=17, tolerance=0.03)
    m["bias"]["interval"] = [-0.001, 0.0005]
    assert "its worst level excludes 0, its mean over levels does not" in _text(m)
    # undecided with its printed interval wholly outside the tolerance: the interval that
    # decides differs is printed, and reaches inside
    m = _judged("undecided", (-0.243, -0.153), bias="low", differs=(-0.262, -0.131))
    text = _text(m)
    assert text.startswith("-19.8 [-24.3, -15.3] % (undecided, biased low;")
    assert "decides differs (99.5 % per end), [-26.2, -13.1] %, reaches inside it" in text
    # an undecided interval that crosses the tolerance needs no second one
    assert _text(_judged("undecided", (-0.25, -0.05))).endswith("(undecided)")
    # a strength compared on fewer runs than the row's: the runs compared
    m = _judged("undecided", (-0.2, 0.3), left_out=1)
    m["seeds"] = 2
    assert "3 / 2 runs compared, 1 hardening run left out" in _text(m)
