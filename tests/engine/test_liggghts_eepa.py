"""benchmarks/liggghts_eepa.py without LIGGGHTS: the deck it writes carries the EEPA
parameters in the names, units and ratios of LIGGGHTS 3.8's edinburgh/stiffness model, and its
metric is the documented relative RMS difference."""

from __future__ import annotations

import re

import numpy as np
import pytest

import engine
from benchmarks import liggghts_eepa as lig


def _fixes(deck: str) -> dict[str, str]:
    """property/global name -> its value(s) as written in the deck."""
    out = {}
    for m in re.finditer(r"^fix\s+\S+\s+all\s+property/global\s+(\S+)\s+(\S+)\s+(.*)$", deck, re.M):
        name, style, rest = m.groups()
        vals = rest.split()
        out[name] = vals[-1]
        if style == "peratomtypepair":
            assert vals[0] == "1", name  # one atom type: a 1 x 1 matrix
    return out


@pytest.mark.parametrize("key", list(lig.CASES))
def test_deck_carries_the_case_parameters_in_liggghts_units(key):
    case = lig.CASES[key]
    deck = lig.deck(case, top=0.0873)
    p = _fixes(deck)
    assert float(p["LoadingStiffness"]) == case.k1  # K1 itself [N/m^n]
    assert float(p["UnloadingStiffness"]) == pytest.approx(case.k2 / case.k1)  # the ratio
    assert float(p["UnloadingStiffness"]) == pytest.approx(5.0)
    assert float(p["overlapExponent"]) == case.n  # dex
    assert float(p["adhesionExponent"]) == case.chi  # cex
    assert float(p["pullOffForce"]) == case.f0  # f0 [N], <= 0
    assert float(p["surfaceEnergy"]) == 0.0  # with fixKc off: computed kadh = 0
    assert float(p["coefficientRestitution"]) == case.platen_restitution
    assert float(p["coefficientFriction"]) == case.mu_s
    assert float(p["coefficientRollingFriction"]) == case.mu_r
    assert float(p["youngsModulus"]) == lig.WALL_E
    assert float(p["poissonsRatio"]) == lig.WALL_NU
    assert "fixKc on" not in deck
    assert re.search(
        r"^pair_style\s+gran model edinburgh/stiffness tangential history "
        r"rolling_friction cdt\s*$",
        deck,
        re.M,
    )
    assert deck.count("wall/gran model hertz") == 2  # both platens Hertz, as in demscale
    # the same law in demscale
    law = case.eepa()
    assert (law.k1, law.k2, law.n, law.chi, law.f0, law.kadh) == (
        case.k1,
        case.k2,
        case.n,
        case.chi,
        case.f0,
        0.0,
    )


def test_deck_protocol_skin_and_platen_motion():
    deck = lig.deck(lig.CASES["2"], top=0.0873)
    skin = float(re.search(r"^neighbor\s+(\S+)\s+bin", deck, re.M).group(1))
    travel = lig.PLATEN_SPEED * lig.NSTEPS * lig.DT
    assert skin == lig.SKIN and skin / 2 > travel  # no list rebuild while the platen moves
    assert re.search(r"^neigh_modify\s+delay 0", deck, re.M)
    assert re.search(rf"^timestep\s+{lig.DT!r}$", deck, re.M)
    assert lig.CASES["2"].steps == (lig.NEQUIL, lig.NSTEPS, lig.EVERY, lig.WINDOW)
    assert re.search(rf"^run\s+{lig.NEQUIL + lig.NSTEPS}$", deck, re.M)  # one run: one setup
    assert re.search(
        rf"^variable\s+vz equal -{lig.PLATEN_SPEED!r}\*\(step>{lig.NEQUIL}\)$", deck, re.M
    )
    assert re.search(r"scale 0\.05 &\n\s+move 0\.0 0\.0 0\.0873$", deck, re.M)
    assert re.search(
        rf"ave/time {lig.EVERY} {lig.WINDOW // lig.EVERY} {lig.WINDOW} "
        r"f_topmesh\[3\]",
        deck,
    )
    assert "fix             grav all gravity 9.81 vector 0.0 0.0 -1.0" in deck


def test_a_smaller_time_step_keeps_the_protocol_times():
    case = lig.CASES["2c"]
    assert case.dt == lig.DT / 2
    deck = lig.deck(case, top=0.0873)
    assert re.search(r"^timestep\s+5e-06$", deck, re.M)
    assert re.search(rf"^run\s+{2 * (lig.NEQUIL + lig.NSTEPS)}$", deck, re.M)
    assert re.search(rf"ave/time {2 * lig.EVERY} {lig.WINDOW // lig.EVERY} {2 * lig.WINDOW} ", deck)
    assert re.search(rf"step>{2 * lig.NEQUIL}\)$", deck, re.M)


def test_cases_match_the_issue():
    c = lig.CASES
    assert (c["1"].mu_s, c["1"].mu_r, c["1"].f0) == (0.0, 0.0, 0.0)
    assert (c["2"].mu_s, c["2"].mu_r, c["2"].f0) == (0.5, 0.001, 0.0)
    assert (c["3"].f0, c["3"].friction_cap) == (-0.4, "adhesive")
    assert (c["4"].f0, c["4"].friction_cap) == (-0.4, "normal")
    assert (c["5"].n, c["5"].k1, c["5"].k2) == (1.0, 5e3, 2.5e4)
    for case in c.values():
        assert case.k2 / case.k1 == 5.0 and case.restitution == 0.5
        if not case.diagnostic:
            assert case.kt_ratio == 1.0  # LIGGGHTS: kt = kn
            assert case.dt == lig.DT
        wall = case.wall_law()
        assert (wall.mu, wall.mu_r) == (case.mu_s, case.mu_r)
        assert wall.restitution == (0.5 if case.lig_restitution is None else case.lig_restitution)
        assert case.diagnostic == (case.key not in ("1", "2", "3", "4", "5"))


def test_matched_restitution_gives_liggghts_the_damping_of_demscale_at_the_overlap():
    # n = 1: the tangent stiffness is K1 itself, nothing to match
    assert lig.matched_restitution(0.5, 1.0, 1e-4) == pytest.approx(0.5)
    e = lig.matched_restitution(0.5, 1.5, lig.D_REF)
    zeta = engine.contact.limits.damping_ratio
    m, k1 = 6.5e-5, 5e5
    c_liggghts = 2 * zeta(e) * (m * k1) ** 0.5
    c_demscale = 2 * zeta(0.5) * (m * 1.5 * k1 * lig.D_REF**0.5) ** 0.5
    assert c_liggghts == pytest.approx(c_demscale)
    assert lig.CASES["1b"].lig_restitution == pytest.approx(e, abs=5e-4)


def test_rel_rms_is_zero_for_identical_curves_and_known_for_an_offset():
    x = np.linspace(0, 0.06, 101)
    y = 1e4 * x**1.5
    assert lig.rel_rms(x, y, x, y) == 0.0
    # a constant reference 2.0 and an offset of 0.1: 5 %
    assert lig.rel_rms(x, np.full_like(x, 2.1), x, np.full_like(x, 2.0)) == pytest.approx(5.0)
    # a curve 3 % above its reference everywhere: 3 %
    assert lig.rel_rms(x, 1.03 * y, x, y) == pytest.approx(3.0)
    # curve a on other strain points is interpolated onto the reference's
    xa = np.linspace(0, 0.06, 37)
    assert lig.rel_rms(xa, 2 * xa + 1, x, 2 * x + 1) == pytest.approx(0.0, abs=1e-12)
    with pytest.raises(ValueError):
        lig.rel_rms(x, y, x + 1.0, y)


def test_parse_log_reads_thermo_rows_loop_time_and_builds():
    text = """\
    Step    Atoms         KinEng            avg       topmesh[            CPU
       0     2025 9.5e-09 0 0 0
     500     2025 0.000487 12.5 13.0 4.0
Loop time of 43.19 on 1 procs for 500 steps with 2025 atoms
Neighbor list builds = 0
Dangerous builds = 0
"""
    out = lig.parse_log(text)
    assert out["rows"] == [[0, 2025, 9.5e-09, 0, 0], [500, 2025, 0.000487, 12.5, 13.0]]
    assert (out["seconds"], out["procs"], out["builds"], out["dangerous"]) == (43.19, 1, 0, 0)


def test_cases_that_differ_only_in_a_demscale_option_share_one_liggghts_deck():
    # the Coulomb cap convention and kt_ratio are demscale options: one LIGGGHTS run each
    ids = {k: lig.deck_id(c) for k, c in lig.CASES.items()}
    assert ids["3"] == ids["4"]
    assert ids["2c"] == ids["2d"]
    assert len(set(ids.values())) == len(ids) - 2


def test_spread_runs_are_named_once():
    assert len(set(lig.SPREAD_CODES)) == len(lig.SPREAD_CODES)
    assert "demscale-jitter1" in lig.SPREAD_CODES and "liggghts-jitter1" in lig.SPREAD_CODES
    x = np.arange(3.0)
    assert np.array_equal(lig.jittered(x, 0.0, 1), x)
    assert np.abs(lig.jittered(x, 1e-9, 1) - x).max() < 1e-8
