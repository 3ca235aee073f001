"""The LIGGGHTS deck of a uniaxial test (engine.io.liggghts_deck), its output read back
(engine.io.liggghts_read) and judged, and the two commands (demscale export-test,
judge-liggghts). Without LIGGGHTS: the deck's numbers parsed back against the test's, and a
stored LIGGGHTS run (tests/data/liggghts/tiny, made by LIGGGHTS 3.8 from this deck) read
back and held to the stopping rules and demscale's own measures. Where Debian's
``liggghts`` is installed, the deck is run again and demscale's measures of one state are
compared with the deck's (tests/test_liggghts_deck_run.py does that).

Regenerate the stored data (LIGGGHTS installed) with one command:

    .venv/bin/python -m tests.test_liggghts_deck
"""

from __future__ import annotations

import json
import math
import re
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import engine
from engine.io import liggghts_deck as ld
from engine.io.liggghts_read import (
    judge_runs,
    parse_curves,
    read_dump,
    read_output,
    save_output,
)
from engine.io.store import load_run
from engine.uniaxial.driver import stages_of
from engine.uniaxial.measures import FailureDetector, interior_measures

DATA = Path(__file__).resolve().parent / "data" / "liggghts"
TINY = DATA / "tiny"


def tiny_test(**changes) -> engine.UniaxialTest:
    """A 29-sphere test that LIGGGHTS runs in two seconds: (b)'s law without plastic unloading
    (LIGGGHTS' plastic edinburgh law does not settle in a periodic cell, docs/LIGGGHTS_DECK.md)
    and a weaker adhesion, a fast platen, short stages, a sample every 2 ms."""
    law = engine.BilinearAdhesive(k1=5e3, k2=5e3, f0=-0.2, mu_s=0.5, mu_r=0.001, restitution=0.4)
    fields = dict(
        pair_law=law,
        cell=(0.0125, 0.0125, 0.02),
        platen_speed=0.05,
        release_time=0.02,
        max_unconfined_strain=0.05,
        output_interval=2e-3,
        max_stage_time=2.0,
    )
    return engine.preset("quick", protocol="seed", **{**fields, **changes})


def plastic_test() -> engine.UniaxialTest:
    """The tiny test with (b)'s plastic law, for the deck's text."""
    law = engine.BilinearAdhesive(k1=5e3, k2=2.5e4, f0=-0.8, mu_s=0.5, mu_r=0.001, restitution=0.4)
    return tiny_test(pair_law=law)


def numbers(line: str) -> list[float]:
    out = []
    for w in line.split():
        try:
            out.append(float(w))
        except ValueError:
            pass
    return out


def lines(text: str, start: str) -> list[str]:
    return [x for x in text.splitlines() if x.startswith(start)]


def one(text: str, start: str) -> str:
    found = lines(text, start)
    assert len(found) == 1, (start, found)
    return found[0]


# ---------------------------------------------------------------------------- the deck
def test_the_deck_holds_the_tests_numbers():
    t = plastic_test()
    law, wall, mat = t.pair_law, t.wall_law, t.wall_material
    text = ld.deck(t)
    assert numbers(one(text, "timestep"))[0] == t.resolved_dt()
    S = round(t.output_interval / t.resolved_dt())
    runs = [numbers(x) for x in lines(text, "run ") if "pre no" in x]
    assert runs and all(r == [S] for r in runs)
    assert one(text, "boundary") == "boundary p p f"
    assert "edinburgh/stiffness tangential history rolling_friction cdt" in one(text, "pair_style")

    def prop(name: str) -> list[float]:
        return numbers(next(x for x in lines(text, "fix m") if f" {name} " in x))

    assert prop("youngsModulus") == [wall.E, mat.E]
    assert prop("poissonsRatio") == [wall.nu, mat.nu]
    assert prop("coefficientFriction") == [2, law.mu_s, wall.mu, wall.mu, wall.mu]
    assert prop("coefficientRestitution") == [2, law.restitution, *[wall.restitution] * 3]
    assert prop("coefficientRollingFriction") == [2, law.mu_r, *[wall.mu_r] * 3]
    assert prop("LoadingStiffness") == [2, *[law.k1] * 4]
    assert prop("UnloadingStiffness") == [2, *[law.k2 / law.k1] * 4]
    assert prop("pullOffForce") == [2, *[law.f0] * 4]
    assert prop("overlapExponent") == [1.0] and prop("adhesionExponent") == [1.0]
    assert prop("surfaceEnergy") == [2, 0, 0, 0, 0]
    assert numbers(one(text, "fix grav"))[0] == t.gravity
    # the stages' stopping rules, with the numbers the driver uses
    done = [x for x in lines(text, "variable done equal")]
    assert len(done) == 6
    fill, pre, cons, unl, rel, unc = done
    g, H = t.gravity, t.cell[2]
    m = t.density * 4 / 3 * math.pi * t.radius**3
    e_settle = t.settle_ke * t.n_particles * m * g * t.radius
    fall, energy = (float(x) for x in re.findall(r"[<>]=([-0-9.e+]+)\)", fill))
    assert fall == math.sqrt(2 * H / g)
    assert energy == pytest.approx(e_settle, rel=1e-12)
    assert pre.endswith(f"v_stop>={t.pre_stress!r}")
    assert cons.endswith(f"v_stop>={t.consolidation_stress!r}")
    assert unl.endswith(f"v_stop<={t.unloaded_stress * t.consolidation_stress!r}")
    t_min = 5 * math.sqrt(2 * t.radius / g)
    assert f">={t_min!r})" in rel and f">={max(t_min, t.release_time)!r})" in rel
    assert f"(v_strain>={t.max_unconfined_strain!r})" in unc
    assert f"(v_sdet<{1 - t.failure_drop!r}*v_peak)" in text
    assert one(text, "variable sdet equal") == "variable sdet equal v_stop"
    inner = ld.deck(replace(t, strength_from="interior"))
    assert one(inner, "variable sdet equal") == "variable sdet equal v_sin"
    assert f">={t.failure_strain!r}" in one(text, "variable fdone")
    max_steps = round(t.max_stage_time / t.resolved_dt())
    assert all(x.endswith(f">={max_steps}") for x in lines(text, "variable over equal"))
    # the platen: placed 0.05 R above the bed, moved at the platen speed
    assert one(text, "variable zp equal").endswith(f"+{0.05 * t.radius!r}")
    speeds = [numbers(x)[0] for x in lines(text, "variable vplaten equal")]
    v = t.platen_speed
    assert speeds == [0.0, -v, v, 0.0, 0.0, -v, 0.0]
    assert (
        one(text, "fix wallf").split("zplane ")[1].startswith(repr(t.pour_region[2] + 4 * t.radius))
    )


def test_a_hold_stage_is_written_between_consolidation_and_unloading():
    # hold_time: the plate stopped after the consolidation, the stage over once hold_time
    # has passed and the kinetic energy is below the settle energy (the driver's rule);
    # its code in curves.txt is the last, so files written before it read the same
    t = replace(plastic_test(), hold_time=0.0125)
    text = ld.deck(t)
    assert "loop_hold" not in ld.deck(plastic_test())
    assert text.index("end_consolidation") < text.index("loop_hold") < text.index("loop_unloading")
    done = [x for x in lines(text, "variable done equal")]
    assert len(done) == 7
    hold = done[3]
    m = t.density * 4 / 3 * math.pi * t.radius**3
    e_settle = t.settle_ke * t.n_particles * m * t.gravity * t.radius
    rest, energy = (float(x) for x in re.findall(r"[<>]=([-0-9.e+]+)\)", hold))
    assert rest == t.hold_time and energy == pytest.approx(e_settle, rel=1e-12)
    speeds = [numbers(x)[0] for x in lines(text, "variable vplaten equal")]
    v = t.platen_speed
    assert speeds == [0.0, -v, 0.0, v, 0.0, 0.0, -v, 0.0]
    assert ld.STAGES[-1] == "hold" and ld.STAGES.index("unloading") == 3
    # hold_quiet: the step of the last sample above the energy kept in tq, from the start
    q = ld.deck(replace(t, hold_quiet=0.005))
    hold = [x for x in lines(q, "variable done equal")][3]
    assert hold.endswith(f"*((v_n-v_tq)*{t.resolved_dt()!r}>={0.005!r})")
    assert "variable tq equal ${t0}" in q
    assert one(q, 'if "${kin} >').endswith('then "variable tq equal ${n}"')
    # in order: the stage's start, tq from it, the loop: a run, then tq from its sample
    tq = q.index("variable tq equal ${t0}")
    assert q.rindex("variable t0 equal", 0, tq) > q.index("label end_consolidation")
    run = q.index("run ", q.index("label loop_hold"))
    assert tq < run < q.index('if "${kin} >') < q.index("jump SELF loop_hold")


def test_the_deck_folder_holds_demscales_cloud_to_the_last_bit(tmp_path):
    t = plastic_test()
    ld.write_deck(t, tmp_path)
    pos, radii = t.initial_packing()
    text = (tmp_path / ld.DATA).read_text().splitlines()
    rows = np.array([[float(v) for v in x.split()] for x in text[text.index("Atoms") + 2 :]])
    assert rows.shape == (t.n_particles, 7)
    assert np.array_equal(rows[:, 0], np.arange(1, t.n_particles + 1))
    assert np.array_equal(rows[:, 2] / 2, radii)
    assert np.array_equal(rows[:, 4:7], pos)
    assert set(rows[:, 1]) == {1.0} and set(rows[:, 3]) == {t.density}
    lx, ly = t.cell[:2]
    stl = (tmp_path / ld.PLATE).read_text()
    corners = {tuple(numbers(x)[:2]) for x in stl.splitlines() if "vertex" in x}
    assert corners == {(0.0, 0.0), (lx, 0.0), (0.0, ly), (lx, ly)}
    wide = (tmp_path / ld.PLATE_WIDE).read_text()
    corners = {tuple(numbers(x)[:2]) for x in wide.splitlines() if "vertex" in x}
    assert corners == {(a * lx, b * ly) for a in (-1.0, 2.0) for b in (-1.0, 2.0)}
    assert engine.UniaxialTest.from_dict(json.loads((tmp_path / ld.TEST).read_text())) == t


def test_the_deck_refuses_what_liggghts_cannot_take():
    law = engine.EEPA(k1=5e5, k2=2.5e6, kadh=10.0, n=1.5, chi=1.5)
    with pytest.raises(engine.ParameterError, match=r"UniaxialTest\.pair_law\.kadh"):
        ld.deck(tiny_test(pair_law=law))
    pair = engine.HertzMindlin(E=2e8, nu=0.25)
    with pytest.raises(engine.ParameterError, match=r"UniaxialTest\.wall_law\.E"):
        ld.deck(tiny_test(pair_law=pair))
    with pytest.raises(engine.ParameterError, match="skin"):
        ld.deck(tiny_test(), skin=-1.0)


def test_an_adhesive_branch_goes_on_liggghts_fixkc_path_for_n_one():
    # kadh > 0 with n = chi = 1: coefficientAdhesionStiffness = kadh / K1 with fixKc on and
    # limitForce off (engine.io.liggghts module docstring); the plastic-reload difference
    # named in the deck's comments
    law = engine.BilinearAdhesive(k1=5e3, k2=2.5e4, f0=-0.2, kadh=2.5e3)
    text = ld.deck(tiny_test(pair_law=law))
    assert numbers(one(text, "fix m12 "))[-4:] == [0.5] * 4
    assert one(text, "pair_style").endswith("fixKc on limitForce off")
    assert "adhesive branch: LIGGGHTS' is plastic" in text
    plain = ld.deck(tiny_test())
    assert "fixKc" not in one(plain, "pair_style")


@pytest.mark.parametrize("field", ["inertial_number"])
def test_a_platen_speed_held_to_an_inertial_number_is_refused(field):
    t = tiny_test()
    if not hasattr(t, field):
        pytest.skip(f"UniaxialTest has no {field} yet")
    value = 1e-3
    try:
        t = replace(t, **{field: value})
    except engine.ParameterError:
        pytest.skip(f"{field} = {value} is not a valid test on its own")
    with pytest.raises(engine.ParameterError, match=rf"UniaxialTest\.{field}"):
        ld.deck(t)


def test_a_hertz_pair_law_and_a_capped_pour():
    w = engine.preset("quick").wall_law
    t = tiny_test(pair_law=engine.HertzMindlin(E=w.E, nu=w.nu, mu=0.4), pour_speed=0.5)
    text = ld.deck(t)
    assert one(text, "pair_style") == "pair_style gran model hertz tangential history"
    # the factor a particle's velocity is scaled by, evaluated as LIGGGHTS would
    cf = one(text, "variable cf atom").split("atom ", 1)[1]
    for vm in (0.0, 0.1, 0.5, 2.0):
        assert eval(cf.replace("v_vm", repr(vm))) == pytest.approx(min(1.0, 0.5 / max(vm, 0.5)))
    assert "velocity all set v_vxn v_vyn v_vzn units box" in text
    # the fill lasts at least the capped column's fall
    fill = lines(text, "variable done equal")[0]
    assert f">={t.pour_height / 0.5!r})" in fill


# ---------------------------------------------------------------------------- the output
def test_a_stored_liggghts_run_is_read_back_with_every_stopping_rule_honoured():
    r = read_output(TINY)
    t = r.test
    assert t == tiny_test()
    assert list(r.stages) == list(stages_of(t))
    S = round(t.output_interval / t.resolved_dt())
    area = t.cell[0] * t.cell[1]
    for name, st in r.stages.items():
        c = st.curves
        assert set(c) == set(engine.uniaxial.results.CURVE_UNITS)
        assert all(np.all(np.isfinite(v)) for v in c.values())
        assert st.steps % S == 0 and st.steps > 0
        assert st.positions.shape == (t.n_particles, 3)
        if name != "unloading":
            assert c["strain"][0] == 0.0
    s = {k: r.stages[k].curves for k in r.stages}
    dt = t.resolved_dt()
    # the fill: past the fall time, settled; the stresses: each target reached on the last
    # sample and not before
    fill = s["fill"]
    e_settle = ld.settle_energy(t)
    assert fill["time"][-1] - fill["time"][0] >= ld.fall_time(t)
    assert fill["kinetic_energy"][-1] <= e_settle
    for stage, target in (
        ("pre_compression", t.pre_stress),
        ("consolidation", t.consolidation_stress),
    ):
        top = s[stage]["stress_top"]
        assert top[-1] >= target and np.all(top[:-1] < target)
    low = t.unloaded_stress * t.consolidation_stress
    assert s["unloading"]["stress_top"][-1] <= low and np.all(
        s["unloading"]["stress_top"][:-1] > low
    )
    u = s["unconfined"]
    det = FailureDetector(t.failure_drop, t.failure_strain)
    fired = [det.update(e, x) for e, x in zip(u["strain"], u["stress_top"])]
    assert (fired[-1] or u["strain"][-1] >= t.max_unconfined_strain) and not any(fired[:-1])
    # the platen at the speed of each stage, from the step it moved
    for stage, v in (("pre_compression", -t.platen_speed), ("unloading", t.platen_speed)):
        gap, time = s[stage]["platen_gap"], s[stage]["time"]
        assert np.allclose(np.diff(gap), v * np.diff(time), rtol=1e-9, atol=1e-15)
    # the deck's interior measures are demscale's, recomputed from each stage's end
    for st in r.stages.values():
        gap = float(st.curves["platen_gap"][-1])
        por, _ = interior_measures(
            st.positions[:, 2], st.radii, np.zeros(len(st.radii)), gap, t.margin, area
        )
        assert st.curves["porosity_interior"][-1] == pytest.approx(por, rel=1e-9, abs=1e-12)
    total = 4 / 3 * math.pi * float(np.sum(r.stages["fill"].radii ** 3))
    assert s["consolidation"]["porosity"][-1] == pytest.approx(
        1 - total / (area * s["consolidation"]["platen_gap"][-1]), rel=1e-12
    )
    sc = r.scalars
    assert sc["particles"] == t.n_particles and sc["dt"] == dt
    assert sc["steps"] == sum(st.steps for st in r.stages.values())
    assert sc["wall_time"] > 0 and sc["unconfined_strength"] == max(u["stress_top"].max(), 0.0)
    assert sc["loading_stiffness"] > 0 and sc["unloading_stiffness"] > sc["loading_stiffness"]


def test_parse_curves_marks_errors_and_refuses_torn_lines():
    text = (TINY / ld.CURVES).read_text()
    head = text.split("# end fill")[0]
    p = parse_curves(head + "# error fill 400000 0 0.05 0.001\n# done 400000\n")
    assert p["error"]["stage"] == "fill" and p["error"]["step"] == 400000 and p["done"]
    with pytest.raises(ValueError, match="values, not"):
        parse_curves(head + "0 100 0.05\n")


def test_a_hold_stages_samples_read_back_under_its_code():
    # the hold's code in curves.txt is the last of ld.STAGES: a sample line starting with it
    # belongs to the hold, the other stages' codes unchanged
    text = (TINY / ld.CURVES).read_text()
    head, _, _ = text.partition("# begin unloading")
    last = [x for x in head.splitlines() if x and not x.startswith("#")][-1].split()
    code = ld.STAGES.index("hold")
    row = " ".join([str(code), *last[1:]])
    hold = f"# begin hold {last[1]} 0.05\n{row}\n{row}\n# end hold {last[1]}\n"
    p = parse_curves(head + hold)
    assert list(p["stages"])[-2:] == ["consolidation", "hold"]
    assert p["stages"]["hold"]["rows"].shape == (2, len(ld.COLUMNS))
    assert p["stages"]["hold"]["rows"][0, 0] == code == 6


def test_a_run_that_stopped_at_a_stage_bound_is_a_stage_error(tmp_path):
    folder = tmp_path / "deck"
    shutil.copytree(TINY, folder)
    text = (folder / ld.CURVES).read_text()
    (folder / ld.CURVES).write_text(
        text.split("# end fill")[0] + "# error fill 1000000 -0 0.05 0.0157\n# done 1000000\n"
    )
    with pytest.raises(engine.StageError) as e:
        read_output(folder)
    assert e.value.stage == "fill" and "LIGGGHTS" in str(e.value)
    out = load_run(save_output(folder, tmp_path / "stopped.h5"))
    assert isinstance(out, str) and "stage fill" in out


def test_stored_read_back_and_judged_against_demscale(tmp_path):
    path = save_output(TINY, tmp_path / "lig.h5")
    back = load_run(path)
    direct = read_output(TINY)
    for name, st in direct.stages.items():
        for k, v in st.curves.items():
            assert np.array_equal(back.stages[name].curves[k], v)
    import h5py

    with h5py.File(path, "r") as f:
        assert "LIGGGHTS" in json.loads(f.attrs["producer"])["code"]
    refs = [load_run(DATA / f"demscale-s{s}.h5") for s in (1, 2)]
    assert all(r.test == replace(tiny_test(), seed=s) for r, s in zip(refs, (1, 2)))
    out = judge_runs([back, "LIGGGHTS: stage fill did not ..."], refs)
    assert out["seeds"] == 1 and out["reference_seeds"] == 2 and len(out["failed"]) == 1
    assert out["verdict"] in ("equivalent", "differs", "undecided")
    names = [m["metric"] for m in out["metrics"]]
    assert names == list(engine.DEFAULT_TOLERANCES)
    for m in out["metrics"]:
        assert m["verdict"] in ("equivalent", "differs", "undecided")
    none = judge_runs(["LIGGGHTS: stage fill did not ..."], refs)
    assert none["verdict"] == "not judged" and "stopped" in none["reason"]
    with pytest.raises(ValueError, match="at least 2"):
        judge_runs([back], refs[:1])


def test_read_dump_orders_atoms_by_id():
    pos, rad = read_dump(TINY / ld.STAGE_DUMP.format("fill"))
    assert pos.shape == (len(rad), 3) and np.all(rad > 0)


# ---------------------------------------------------------------------------- the commands
def test_export_test_and_judge_liggghts_commands(tmp_path, capsys):
    from demscale.cli import main

    law = tmp_path / "law.json"
    law.write_text(json.dumps({"type": "BilinearAdhesive", "k1": 5e3, "k2": 5e3, "f0": -0.2}))
    assert (
        main(
            [
                "export-test",
                "--preset",
                "quick",
                "--protocol",
                "seed",
                "--law",
                str(law),
                "--seeds",
                "1",
                "2",
                "--out",
                str(tmp_path / "deck"),
            ]
        )
        == 0
    )
    for s in (1, 2):
        t = json.loads((tmp_path / "deck" / f"s{s}" / ld.TEST).read_text())
        assert t["seed"] == s and t["pair_law"]["f0"] == -0.2
        assert (tmp_path / "deck" / f"s{s}" / ld.DECK).exists()
    test = tmp_path / "test.json"
    test.write_text(json.dumps({"preset": "quick", "protocol": "seed", "radius": 5e-3}))
    assert main(["export-test", str(test), "--out", str(tmp_path / "one")]) == 0
    assert json.loads((tmp_path / "one" / ld.TEST).read_text())["radius"] == 5e-3
    # a shear cell has no deck here: refused naming its kind, nothing written
    shear = tmp_path / "shear.json"
    shear.write_text(json.dumps({"type": "ShearTest"}))
    assert main(["export-test", str(shear), "--out", str(tmp_path / "s")]) == 2
    assert "not a ShearTest" in capsys.readouterr().err and not (tmp_path / "s").exists()
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"type": "EEPA", "k1": 5e5, "k2": 2.5e6, "kadh": 1.0}))
    assert (
        main(["export-test", "--preset", "quick", "--law", str(bad), "--out", str(tmp_path / "x")])
        == 2
    )
    assert "kadh" in capsys.readouterr().err
    # the default protocol loads at an inertial number, which a deck cannot hold: refused,
    # naming the field, with nothing written
    args = ["export-test", "--preset", "quick", "--law", str(law), "--out", str(tmp_path / "y")]
    assert main(args) == 2
    assert "inertial_number" in capsys.readouterr().err and not (tmp_path / "y").exists()
    folder = tmp_path / "ran"
    shutil.copytree(TINY, folder)
    refs = [str(DATA / f"demscale-s{s}.h5") for s in (1, 2)]
    out = tmp_path / "verdict.json"
    assert main(["judge-liggghts", str(folder), "--reference", *refs, "--json", str(out)]) == 0
    v = json.loads(out.read_text())
    assert v["seeds"] == 1 and v["reference_seeds"] == 2 and (folder / "liggghts.h5").exists()
    assert "LIGGGHTS (1 run(s)" in capsys.readouterr().out
    # a study's file: its reference runs, or the runs named
    import h5py

    from engine.io.store import write_run_group

    study = tmp_path / "results.h5"
    with h5py.File(study, "w") as f:
        for s, ref in ((1, True), (2, True), (3, False)):
            g = f.create_group(f"runs/ref-s{s}" if ref else "runs/r5mm-x-s1")
            write_run_group(g, load_run(DATA / f"demscale-s{min(s, 2)}.h5"))
            g.attrs["reference"] = ref
    out2 = tmp_path / "v2.json"
    assert (
        main(["judge-liggghts", str(folder), "--reference", str(study), "--json", str(out2)]) == 0
    )
    assert json.loads(out2.read_text())["reference_seeds"] == 2
    args = ["judge-liggghts", str(folder), "--reference", str(study), "--runs", "ref-s1"]
    assert main(args) == 2  # one reference run: no verdict
    assert "at least 2" in capsys.readouterr().err


def test_judge_liggghts_refuses_references_of_another_test(tmp_path, capsys):
    """A verdict compares LIGGGHTS' runs with demscale's runs of the same test: references
    of another cell (or protocol, or interior margin) are refused before anything is judged,
    naming --reference and the field; a coarse model (radius, pair law, time step) is not."""
    from demscale.cli import main
    from engine.io.store import save_run

    folder = tmp_path / "ran"
    shutil.copytree(TINY, folder)
    refs = [load_run(DATA / f"demscale-s{s}.h5") for s in (1, 2)]
    other = []
    for r in refs:
        path = tmp_path / f"other-s{r.test.seed}.h5"
        save_run(path, replace(r, test=replace(r.test, cell=(0.025, 0.025, 0.04))))
        other.append(str(path))
    out = tmp_path / "v.json"
    assert main(["judge-liggghts", str(folder), "--reference", *other, "--json", str(out)]) == 2
    err = capsys.readouterr().err
    assert "--reference" in err and "cell" in err and err.count("\n") == 1, err
    assert not out.exists()
    mixed = [str(DATA / "demscale-s1.h5"), other[1]]
    assert main(["judge-liggghts", str(folder), "--reference", *mixed]) == 2
    assert "not of one test" in capsys.readouterr().err
    # LIGGGHTS' run of the test at another radius, law and time step (as a coarse model is;
    # smaller here: the tiny cell is as narrow as a periodic cell may be)
    base = refs[0].test
    law = replace(base.pair_law, k1=4e3, k2=4e3)
    moved = replace(base, radius=0.8 * base.radius, dt=0.8e-5, pair_law=law)
    from demscale.commands.deck import _check_same_test

    _check_same_test([replace(refs[0], test=moved)], refs)  # no error
    with pytest.raises(ValueError, match="interior_margin"):
        _check_same_test([replace(refs[0], test=replace(moved, interior_margin=0.01))], refs)


def test_export_test_takes_a_calibrated_law_at_its_radius(tmp_path, capsys):
    """demscale calibrate's law.json records its reference_radius: export-test takes it for
    a test of that radius and refuses it, naming --law, for another."""
    from demscale.cli import main

    law = {"type": "BilinearAdhesive", "k1": 5e3, "k2": 5e3, "f0": -0.2}
    ok, bad = tmp_path / "law.json", tmp_path / "law5.json"
    ok.write_text(json.dumps({**law, "reference_radius": 2.5e-3}))
    bad.write_text(json.dumps({**law, "reference_radius": 5e-3}))
    argv = ["export-test", "--preset", "quick", "--protocol", "seed", "--law"]
    assert main([*argv, str(ok), "--out", str(tmp_path / "d")]) == 0
    assert json.loads((tmp_path / "d" / ld.TEST).read_text())["pair_law"]["k1"] == 5e3
    capsys.readouterr()
    assert main([*argv, str(bad), "--out", str(tmp_path / "e")]) == 2
    err = capsys.readouterr().err
    assert "--law" in err and "reference_radius" in err and err.count("\n") == 1, err
    assert not (tmp_path / "e").exists()


def test_export_test_from_a_study_run(tmp_path):
    from demscale.cli import main

    spec = tmp_path / "spec.json"
    body = {
        "reference": {"preset": "quick", "protocol": "seed"},
        "coarse_radii": [5e-3],
        "reference_seeds": [1, 2],
    }
    spec.write_text(json.dumps(body))
    plan = engine.plan(engine.StudySpec.from_dict(json.loads(spec.read_text())))
    key = next(p.key for p in plan.runs if p.rule is not None)
    assert (
        main(["export-test", "--study", str(spec), "--run", key, "--out", str(tmp_path / "d")]) == 0
    )
    want = next(p.test for p in plan.runs if p.key == key)
    assert engine.UniaxialTest.from_dict(json.loads((tmp_path / "d" / ld.TEST).read_text())) == want
    assert (
        main(["export-test", "--study", str(spec), "--run", "nope", "--out", str(tmp_path / "e")])
        == 2
    )


# ---------------------------------------------------------------------------- the data
def make_data() -> None:
    """Regenerate tests/data/liggghts: the tiny test's deck run by LIGGGHTS (the folder
    without LIGGGHTS' screen output) and demscale's runs of it, seeds 1 and 2."""
    import subprocess

    from engine.io.store import save_run

    if TINY.exists():
        shutil.rmtree(TINY)
    ld.write_deck(tiny_test(), TINY)
    subprocess.run(["liggghts", "-in", ld.DECK], cwd=TINY, check=True, stdout=subprocess.DEVNULL)
    for s in (1, 2):
        run = engine.run_uniaxial(replace(tiny_test(), seed=s))
        save_run(DATA / f"demscale-s{s}.h5", run, keep_particles=False)
    print(f"wrote {TINY} and demscale-s1.h5, demscale-s2.h5")


if __name__ == "__main__":
    make_data()
