"""Student's t, Welch and Fieller (engine.study.intervals) against closed forms and tables."""

from __future__ import annotations

import math

import numpy as np
import pytest

from engine.study import intervals as iv


@pytest.mark.parametrize(
    ("p", "df", "t"),
    [
        (0.975, 1, 12.706204736174698),  # closed form: tan(pi (p - 1/2))
        (0.95, 2, 2.919985580353726),  # closed form: (2p - 1) / sqrt(2 p (1 - p))
        (0.975, 10, 2.228138851986274),
        (0.99, 5, 3.364929998907217),
        (0.995, 30, 2.749995653567),
        (0.95, math.inf, 1.6448536269514722),
    ],
)
def test_quantiles_match_tables(p, df, t):
    assert iv.t_quantile(p, df) == pytest.approx(t, rel=1e-9)
    assert iv.t_cdf(t, df) == pytest.approx(p, rel=1e-12)


def test_closed_forms_for_one_and_two_degrees_of_freedom():
    for p in (0.6, 0.9, 0.99, 0.9999):
        assert iv.t_quantile(p, 1) == pytest.approx(math.tan(math.pi * (p - 0.5)), rel=1e-9)
        assert iv.t_quantile(p, 2) == pytest.approx(
            (2 * p - 1) / math.sqrt(2 * p * (1 - p)), rel=1e-9
        )
    assert iv.t_quantile(0.1, 3) == pytest.approx(-iv.t_quantile(0.9, 3))


def test_fractional_degrees_of_freedom_against_the_integrated_density():
    x = np.linspace(-400.0, 2.5, 400_001)
    for df in (1.3, 2.7):
        pdf = np.array([iv.t_pdf(v, df) for v in x[::100]])
        xs = x[::100]
        integral = np.trapezoid(pdf, xs) + iv.t_cdf(-400.0, df)
        assert iv.t_cdf(2.5, df) == pytest.approx(integral, rel=2e-4)


def test_welch_degrees_of_freedom():
    c = np.array([1.0, 2.0, 3.0])
    r = np.array([1.0, 1.5, 2.0, 2.5])
    d, u, df = iv.welch(c, r)
    vc, vr = 1.0 / 3, (5 / 12) / 4
    assert d == pytest.approx(0.25)
    assert u == pytest.approx(math.sqrt(vc + vr))
    assert df == pytest.approx((vc + vr) ** 2 / (vc**2 / 2 + vr**2 / 3))


def test_fieller_without_noise_is_the_ratio_and_widens_with_it():
    rho, lo, hi, df = iv.fieller([2.0, 2.0], [1.0, 1.0], 0.05)
    assert rho == lo == hi == 2.0 and df == 1
    rho, lo, hi, _ = iv.fieller([2.0, 2.2, 1.8], [1.0, 1.1, 0.9], 0.05)
    assert lo < rho < hi and rho == pytest.approx(2.0)
    # a reference mean not told apart from zero gives no bounds
    _, lo, hi, _ = iv.fieller([1.0, 1.2], [0.1, -0.1], 0.05)
    assert lo == -math.inf and hi == math.inf


def test_hsu_degrees_of_freedom():
    assert iv.hsu_df(2, 12) == 1 and iv.hsu_df(5, 3) == 2
