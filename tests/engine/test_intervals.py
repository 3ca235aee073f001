"""Student's t, Welch and the log-ratio interval (engine.study.intervals) against closed
forms and tables."""

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


def test_log_ratio_without_noise_is_the_ratio_and_widens_with_it():
    rho, lo, hi, df = iv.log_ratio_interval([2.0, 2.0], [1.0, 1.0], 0.05)
    assert rho == lo == hi == pytest.approx(2.0) and df == 1
    rho, lo, hi, _ = iv.log_ratio_interval([2.0, 2.2, 1.8], [1.0, 1.1, 0.9], 0.05)
    assert lo < rho < hi
    # geometric means: 2 x the reference exactly when each value is doubled
    assert iv.log_ratio_interval([2.0, 2.4, 1.6], [1.0, 1.2, 0.8], 0.05)[0] == pytest.approx(2.0)
    with pytest.raises(ValueError, match="positive"):
        iv.log_ratio_interval([1.0, -1.0], [1.0, 2.0], 0.05)


def test_interval_degrees_of_freedom_lie_between_hsu_and_welch():
    rng = np.random.default_rng(0)
    for nc, nr in [(3, 3), (3, 12), (12, 3), (7, 4)]:
        vc, vr = rng.random(50) + 1e-3, rng.random(50) + 1e-3
        df = iv.interval_df(nc, nr, vc, vr)
        ws = (vc + vr) ** 2 / (vc**2 / (nc - 1) + vr**2 / (nr - 1))
        assert np.all(df >= min(nc, nr) - 1 - 1e-12) and np.all(df <= ws + 1e-9)
    # one side carrying all the variance: its own n - 1
    assert iv.interval_df(5, 9, 1.0, 0.0) == pytest.approx(4.0)
    assert iv.interval_df(2, 9, 1.0, 1.0) == 1.0  # two seeds: Hsu
    assert iv.interval_df(4, 4, 0.0, 0.0) == math.inf


def test_vector_quantiles_are_the_scalar_ones():
    df = np.array([1.0, 2.5, 7.0, math.inf])
    q = iv.t_upper_quantiles(0.025, df)
    assert q == pytest.approx([iv.t_quantile(0.975, d) for d in df], rel=1e-12)


def test_hsu_degrees_of_freedom():
    assert iv.hsu_df(2, 12) == 1 and iv.hsu_df(5, 3) == 2


def test_the_number_paths_give_the_array_paths_doubles():
    """difference_interval and interval_df take a path of Python numbers for one level (the
    seed allocator asks for hundreds of thousands of intervals): the same doubles as the
    array path, which a third level forces, for own, pooled, shared and zero spreads."""
    from engine.study.comparison import difference_interval

    rng = np.random.default_rng(3)
    cases = [(2, 3, None, None, False), (3, 5, 7.0, 2.0, False), (4, 4, 9.0, 9.0, True)]
    for nc, nr, dfc, dfr, shared in cases:
        for vc, vr in [(0.0, 0.0), (0.0, 0.3), *rng.uniform(0.01, 2.0, (20, 2))]:
            d = float(rng.normal())
            ref = difference_interval(
                np.array([d, 0.0, 0.0]), np.array([vc, 1, 1]), np.array([vr, 1, 1]),
                nc, nr, dfc, dfr, 0.05, shared,
            )  # fmt: skip
            one = difference_interval(np.array([d]), np.array([vc]), np.array([vr]),
                                      nc, nr, dfc, dfr, 0.05, shared)  # fmt: skip
            num = difference_interval(d, float(vc), float(vr), nc, nr, dfc, dfr, 0.05, shared)
            for a, b, c in zip(ref, one, num, strict=True):
                assert np.shape(b) == (1,) and np.shape(c) == ()
                assert a[0].hex() == float(b[0]).hex() == float(c).hex()
            df_arr = iv.interval_df(
                nc, nr, np.array([vc, 1.0]), np.array([vr, 1.0]), dfc, dfr, shared
            )
            assert (
                float(df_arr[0]).hex()
                == float(iv.interval_df(nc, nr, vc, vr, dfc, dfr, shared)).hex()
            )
