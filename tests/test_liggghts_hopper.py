"""The hopper as a LIGGGHTS 3.8 deck (engine.io.liggghts_hopper): its files and refusals here,
and where Debian's ``liggghts`` is installed a short run of the tiny hopper's deck (100
particles, about 11,000 steps: about 3 s)."""

from __future__ import annotations

import json
import math
import shutil
import subprocess

import numpy as np
import pytest

import engine
from engine.hopper.scene import build_hopper
from engine.io import liggghts_hopper as lh

D = 5e-3  # particle diameter [m]


def tiny(**kw) -> engine.HopperTest:
    return engine.HopperTest(**{"outlet_width": 6 * D, "particles": 100, **kw})


def lines(text: str, start: str) -> list[str]:
    return [x for x in text.splitlines() if x.startswith(start)]


def test_the_deck_folder_holds_the_hoppers_fill_walls_and_gate(tmp_path):
    t = tiny()
    path = lh.write_hopper_deck(t, tmp_path)
    text = path.read_text()
    geo = build_hopper(t)
    # the fill: demscale's own spheres, one line each, in the deck's box
    atoms = (tmp_path / lh.FILL).read_text().split("Atoms\n\n")[1].splitlines()
    assert len(atoms) == t.n_particles
    xyz = np.array([[float(v) for v in a.split()[4:]] for a in atoms])
    assert np.array_equal(xyz, geo.scene.positions)
    # the walls and the gate: demscale's meshes, the slot's cut to its periodic depth
    for name, i in (("wall_0.stl", 0), ("wall_1.stl", 1), (lh.GATE, geo.gate_mesh)):
        m = engine.Mesh.from_stl(tmp_path / name)
        want = geo.scene.meshes[i].vertices.copy()
        want[:, 1] = np.clip(want[:, 1], 0.0, t.depth)
        assert np.allclose(np.sort(m.vertices, axis=0), np.sort(want, axis=0), rtol=0, atol=1e-12)
    assert lines(text, "boundary") == ["boundary m p f"]
    assert lines(text, "fix walls") == [
        "fix walls all wall/gran model hertz tangential history mesh n_meshes 3 meshes "
        "wall0 wall1 gate"
    ]
    (floor,) = lines(text, "fix floor")
    assert float(floor.split()[-1]) == -geo.catch_depth
    assert lines(text, "fix movegate") == [
        "fix movegate all move/mesh mesh gate linear/variable v_zero v_zero v_vgate"
    ]
    assert json.loads((tmp_path / lh.HOPPER_TEST).read_text()) == t.to_dict()
    # a cone: one wall mesh, no periodic axis
    text = lh.hopper_deck(tiny(shape="cone"))
    assert lines(text, "boundary") == ["boundary m m f"]
    assert "meshes wall0 gate" in text


def test_the_deck_refuses_what_liggghts_cannot_take():
    pair = engine.HertzMindlin(E=2e8, nu=0.25)
    with pytest.raises(engine.ParameterError, match=r"HopperTest\.wall_law\.E"):
        lh.hopper_deck(tiny(pair_law=pair))
    with pytest.raises(engine.ParameterError, match="skin"):
        lh.hopper_deck(tiny(), skin=0.0)
    with pytest.raises(engine.ParameterError, match="max_steps"):
        lh.hopper_deck(tiny(), max_steps=0)


@pytest.mark.skipif(shutil.which("liggghts") is None, reason="no liggghts")
def test_liggghts_runs_the_tiny_hoppers_deck(tmp_path):
    # a gate opened at 1 mm/s holds the fill back for longer than the stop criterion's first
    # window (arch_wait = 2 free-fall times, 111 samples): the deck stops the discharge at
    # that window's end, as demscale would; the settling is cut short at 6000 steps
    t = tiny(gate_speed=1e-3, arch_wait=2.0)
    lh.write_hopper_deck(t, tmp_path, dump_every=50, max_steps=6000)
    run = subprocess.run(
        ["liggghts", "-in", lh.HOPPER_DECK],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 0, run.stdout[-2000:]
    assert "ERROR" not in run.stdout
    out = lh.read_discharge(tmp_path)
    events = [" ".join(w for w in e.split() if w.isalpha()) for e in out["events"][1:]]
    assert events == [
        "begin settle",
        "cut settle",
        "end settle",
        "begin discharge",
        "stopped",
        "end discharge",
        "done",
    ]
    step_of = {" ".join(e.split()[:-1]): int(e.split()[-1]) for e in out["events"][1:]}
    d = out["stage"] == 1
    every = int(np.diff(out["step"][d])[0])  # steps per sample
    wait = math.ceil(t.arch_wait * t.free_fall_time / t.output_interval)  # samples
    assert wait == 111 and out["discharged_mass"][-1] == 0.0
    assert step_of["stopped"] - step_of["begin discharge"] == wait * every

    # every particle read in and kept, their mass demscale's
    mass = t.n_particles * t.density * 4 / 3 * np.pi * t.radius**3
    assert np.all(out["particles"] == t.n_particles)
    assert np.allclose(out["discharged_mass"] + out["remaining_mass"], mass, rtol=1e-12)
    # the fill falls (it was poured loose) and the discharge's clock starts at the opening
    assert out["ke_trans"][out["stage"] == 0][-1] > 0
    d = out["stage"] == 1
    assert out["time"][d][0] == 0.0 and np.all(np.diff(out["time"][d]) > 0)
    dumps = sorted((tmp_path / lh.DUMP_DIR).glob("*.dump"))
    assert len(dumps) >= 3
    body = (tmp_path / lh.DUMP_DIR / "hopper_settled.dump").read_text().splitlines()
    assert body[3] == str(t.n_particles)  # ITEM: NUMBER OF ATOMS


def test_export_test_writes_a_hoppers_deck(tmp_path, capsys):
    from demscale.cli import main

    spec = tmp_path / "hopper.json"
    spec.write_text(json.dumps({"type": "HopperTest", **tiny().to_dict()}))
    assert main(["export-test", str(spec), "--seeds", "2", "--out", str(tmp_path / "d")]) == 0
    folder = tmp_path / "d" / "s2"
    assert json.loads((folder / lh.HOPPER_TEST).read_text())["seed"] == 2
    assert (folder / lh.HOPPER_DECK).exists() and (folder / lh.GATE).exists()
    out = capsys.readouterr().out
    assert "100 particles" in out and f"liggghts -in {lh.HOPPER_DECK}" in out
    assert "stop criterion reads consecutive windows" in out
    # a bad field is refused naming it
    spec.write_text(json.dumps({"type": "HopperTest", **tiny().to_dict(), "half_angle": 95.0}))
    assert main(["export-test", str(spec), "--out", str(tmp_path / "e")]) == 2
    assert "half_angle" in capsys.readouterr().err
