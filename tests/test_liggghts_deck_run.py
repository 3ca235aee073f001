"""The exported deck run by LIGGGHTS 3.8, where Debian's ``liggghts`` is installed (skipped
elsewhere). One command runs them:

    .venv/bin/python -m pytest tests/test_liggghts_deck_run.py -q

- the tiny test's deck (tests/test_liggghts_deck.py) runs unmodified to its end and gives
  the stored run (tests/data/liggghts/tiny) again, step for step;
- demscale's measures of one state are the deck's: the same packing at rest, one step in
  each code (engine.io.liggghts_deck.probe_deck), read by the deck's formulas and by
  demscale's (contacts, platen force, interior porosity and coordination, the pair virial,
  the interior axial stress, the platen levers).
"""

from __future__ import annotations

import shutil
import subprocess

import numpy as np
import pytest

import engine
from engine.io import liggghts_deck as ld
from engine.io.liggghts_read import read_dump, read_output
from engine.kernel.virial import platen_levers
from engine.uniaxial.measures import interior_axial_stress, interior_measures
from tests.test_liggghts_deck import TINY, tiny_test

pytestmark = pytest.mark.skipif(shutil.which("liggghts") is None, reason="no liggghts")


def liggghts(folder, deck: str) -> None:
    subprocess.run(
        ["liggghts", "-in", deck],
        cwd=folder,
        check=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.STDOUT,
        timeout=300,
    )


@pytest.mark.slow
def test_the_tiny_deck_runs_unmodified_and_gives_the_stored_run(tmp_path):
    ld.write_deck(tiny_test(), tmp_path)
    liggghts(tmp_path, ld.DECK)
    now, stored = read_output(tmp_path), read_output(TINY)
    assert list(now.stages) == list(stored.stages)
    for name, st in now.stages.items():
        assert st.steps == stored.stages[name].steps, name
        for k, v in st.curves.items():
            # the same binary on the same input: the same trajectory, up to the last digits
            # a different processor may round differently in
            assert np.allclose(v, stored.stages[name].curves[k], rtol=1e-9, atol=1e-12), (name, k)


def test_demscales_measures_of_one_state_are_the_decks(tmp_path):
    # a step of 1 ns from rest moves a particle by a dt^2 / 2 (~1e-17 m) and gives it a speed
    # a dt (~1e-8 m/s): damping and tangential forces stay below 1e-6 of the elastic ones,
    # so the two codes' forces are one law's, K1 d + f0 and Hertz, to that precision
    t = tiny_test(dt=1e-9)
    pos, rad = read_dump(TINY / ld.STAGE_DUMP.format("fill"))  # a bed settled by LIGGGHTS
    for name, text in ld.probe_deck(t, pos, rad, steps=1, every=1).items():
        (tmp_path / name).write_text(text)
    liggghts(tmp_path, "in.probe")
    rows = [x.split() for x in (tmp_path / "probe.txt").read_text().splitlines()]
    last = [float(v) for v in rows[-1]]
    c = dict(zip(ld.COLUMNS, last))
    assert c["step"] == 1
    sim = engine.Simulation(t.scene(pos, rad), dt=t.resolved_dt(), threads=1)
    sim.run(1)
    area = t.cell[0] * t.cell[1]
    top = float(sim.wall_positions[1, 2])
    assert c["ztop"] == top
    counts = sim.contact_counts()
    assert c["contacts"] == counts.sum()
    assert c["fbot"] == pytest.approx(-float(sim.wall_forces[0, 2]), rel=1e-9)
    por, coord = interior_measures(sim.positions[:, 2], sim.radii, counts, top, t.margin, area)
    m = t.margin if 0.5 * top - rad.max() > t.margin else max(0.0, 0.5 * top - rad.max())
    assert 1 - c["slab_solid"] / (area * (top - 2 * m)) == pytest.approx(por, rel=1e-9)
    assert c["interior_contacts"] / c["interior_n"] == coord
    sig = sim.pair_stress(1.0)
    for k, col in enumerate(("stress_xx", "stress_yy", "stress_zz")):
        assert -c[col] == pytest.approx(float(sig[k, k]), rel=1e-6), col
    con = sim.contacts()
    s_in = interior_axial_stress(
        sim.positions[:, 2],
        sim.radii,
        con.pairs,
        con.forces,
        con.normals,
        con.overlaps,
        top,
        t.margin,
        area,
    )
    assert -c["interior_stress_zz"] / (area * (top - 2 * m)) == pytest.approx(s_in, rel=1e-6)
    lb, lt = platen_levers(np.ascontiguousarray(sim.positions[:, 2]), sim.radii, 0.0, top)
    assert c["lever_bottom"] / c["touch_bottom"] == pytest.approx(lb, rel=1e-12)
    assert c["touch_top"] == 0 and lt == 0.0
