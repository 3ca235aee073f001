"""The study page's whole-figure plots read at any interval width (review of issue 42 item 2
on the page's screenshot): a 1-dof interval reaching +1e8 % gets a few ticks a decade apart
or more, none crowding zero, and the resolution panels' written intervals stay short."""

from __future__ import annotations

import itertools
import math

import pytest

from engine.io.figures import _pct, _symlog_locator


@pytest.mark.parametrize("lin,top", [(3.0, 35.0), (15.0, 400.0), (15.0, 1.2e8), (10.0, 5e31)])
def test_symlog_ticks_stay_apart(lin, top):
    ticks = list(_symlog_locator(lin, top).tick_values(-top, top))
    positive = [t for t in ticks if t > 0]
    assert 0.0 in ticks and [-t for t in reversed(positive)] == [t for t in ticks if t < 0]
    assert 2 <= len(positive) <= 8, positive  # few enough to read at a panel's height
    assert all(t >= lin / 5 for t in positive)  # none crowding 0 in the linear part
    assert max(positive) <= top
    ratios = [b / a for a, b in itertools.pairwise(positive)]
    assert all(r >= 3 - 1e-9 for r in ratios), positive
    if top / lin > 1e4:  # a wide interval: whole decades (or several) apart
        assert all(math.isclose(math.log10(t), round(math.log10(t))) for t in positive)


def test_percentages_stay_short():
    assert _pct(-36.6) == "-37" and _pct(9999.0) == "+9999"
    assert _pct(3.38e31) == "+3e+31" and _pct(-1.2e5) == "-1e+05"
    assert all(len(_pct(x)) <= 7 for x in (1e4, 5e31, -1e300, 123.4))
