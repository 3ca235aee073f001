"""Laboratory targets (engine.calibration.targets) and a law out to LIGGGHTS and back
(engine.io.liggghts): clear refusals, JSON and fragment round trips, and LIGGGHTS itself on
an exported fragment where it is installed."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from dataclasses import replace

import numpy as np
import pytest

import engine
from engine.calibration import CompressionPoint, LabTargets, StrengthPoint
from engine.io.liggghts import differences, from_liggghts, law_table, to_liggghts

LAB = {
    "tester": "lambda",
    "material": "limestone powder, 20 um",
    "compression": [
        {"stress": 5e3, "porosity": 0.44, "sd": 0.005},
        {"stress": 2e4, "porosity": 0.42, "sd": 0.005},
        {"stress": 1e4, "porosity": 0.425, "sd": 0.005, "branch": "unloading"},
    ],
    "loading_stiffness": 3e5,
    "loading_stiffness_sd": 2e4,
    "k0": 0.45,
    "k0_sd": 0.03,
    "strength": [{"consolidation_stress": 2e4, "strength": 1.4e4, "sd": 1e3}],
}


def test_targets_read_from_json_and_back():
    t = LabTargets.from_dict(json.loads(json.dumps(LAB)))
    assert isinstance(t.compression[0], CompressionPoint)
    assert isinstance(t.strength[0], StrengthPoint)
    assert t.names() == ["compression", "loading_stiffness", "k0", "strength"]
    assert LabTargets.from_dict(t.to_dict()) == t


@pytest.mark.parametrize(
    ("change", "field", "words"),
    [
        ({"tester": "ring_shear"}, "LabTargets.strength", "ring-shear"),
        ({"tester": "uniaxial"}, "LabTargets.k0", "lateral stress sensor"),
        (
            {"compression": [{"stress": 5e3, "porosity": 0.7, "sd": 0.01}]},
            "LabTargets.compression[0].porosity",
            "spheres do not reach it",
        ),
        ({"k0_sd": -0.01}, "LabTargets.k0_sd", ">= 0"),
        (
            {"compression": [{"stress": -1.0, "porosity": 0.4, "sd": 0.01}]},
            "LabTargets.compression[0].stress",
            "> 0",
        ),
        # a value without its uncertainty would be an exact constraint: refused, by name
        (
            {"compression": [{"stress": 5e3, "porosity": 0.4}]},
            "LabTargets.compression[0].sd",
            "required",
        ),
        (
            {"strength": [{"consolidation_stress": 2e4, "strength": 1.4e4}]},
            "LabTargets.strength[0].sd",
            "required",
        ),
        ({"k0_sd": None}, "LabTargets.k0_sd", "uncertainty (1 sd) of k0"),
        ({"loading_stiffness_sd": None}, "LabTargets.loading_stiffness_sd", "repeatability"),
        ({"tester": "shear box"}, "LabTargets.tester", "uniaxial"),
        ({"colour": "red"}, "LabTargets", "fields among"),
    ],
)
def test_a_target_the_test_cannot_measure_is_refused_by_name(change, field, words):
    with pytest.raises(engine.ParameterError) as e:
        LabTargets.from_dict({**LAB, **change})
    assert e.value.field == field and words in str(e.value), str(e.value)


def test_targets_need_at_least_one_measurement():
    with pytest.raises(engine.ParameterError, match="at least one measurement"):
        LabTargets(tester="uniaxial")


LAWS = [
    engine.BilinearAdhesive(k1=5e3, k2=2.5e4, f0=-0.8, kt_ratio=1.0, mu_s=0.5, mu_r=0.001),
    engine.EEPA(k1=5e5, k2=2.5e6, f0=-0.8, n=1.5, chi=1.5, friction_cap="normal"),
    engine.EEPA(k1=2e4, k2=1e5, f0=-0.4, n=1.2, chi=2.0, restitution=0.6),
]
#: a law with an adhesive branch: LIGGGHTS' fixKc-on path (n = chi = 1)
ADHESIVE = engine.BilinearAdhesive(k1=5e3, k2=2.5e4, f0=-0.2, kadh=2.5e3, kt_ratio=1.0)
LAWS.append(ADHESIVE)


@pytest.mark.parametrize("law", LAWS)
def test_a_law_goes_to_liggghts_and_back(law):
    text = to_liggghts(law, note="scaled to R = 5 mm")
    assert "# scaled to R = 5 mm" in text and "edinburgh/stiffness" in text
    assert f"LoadingStiffness peratomtypepair 1 {law.k1!r}" in text
    assert f"UnloadingStiffness peratomtypepair 1 {law.k2 / law.k1!r}" in text
    back = from_liggghts(text, bilinear=isinstance(law, engine.BilinearAdhesive))
    assert type(back) is type(law)
    for name in ("k1", "k2", "f0", "kadh", "mu_s", "mu_r", "restitution"):
        assert getattr(back, name) == pytest.approx(getattr(law, name), rel=1e-15), name
    if isinstance(law, engine.EEPA):
        assert (back.n, back.chi, back.friction_cap) == (law.n, law.chi, "normal")
    # what LIGGGHTS does differently is said in the fragment
    for d in differences(law):
        assert f"# differs: {d}" in text
    # the bilinear law at kt = K1 differs only in its adhesion-aware Coulomb cap; EEPA at
    # n = chi = 1 with the normal cap is LIGGGHTS' law exactly
    assert [d.split(":")[0] for d in differences(LAWS[0])] == ["Coulomb cap"]
    same = engine.EEPA(
        k1=5e3, k2=2.5e4, f0=-0.1, n=1.0, chi=1.0, kt_ratio=1.0, friction_cap="normal"
    )
    assert differences(same) == []


def test_export_refusals_and_the_parameter_table():
    # an adhesive branch only with n = chi = 1 (LIGGGHTS' reset of dmax on it is that case's)
    with pytest.raises(engine.ParameterError, match=r"EEPA\.kadh") as e:
        to_liggghts(engine.EEPA(k1=5e5, k2=2.5e6, kadh=10.0, n=1.5, chi=1.5))
    assert "line 286" in str(e.value)
    text = to_liggghts(ADHESIVE)
    # LIGGGHTS' other adhesive branch (fixKc off: per contact, from a surface energy) and a
    # stiffness ratio it would not read are refused when read back
    with pytest.raises(engine.ParameterError, match="coefficientAdhesionStiffness"):
        from_liggghts(text.replace(" fixKc on", ""))
    with pytest.raises(engine.ParameterError, match="surfaceEnergy"):
        from_liggghts(
            to_liggghts(LAWS[0]).replace(
                "surfaceEnergy peratomtypepair 1 0.0", "surfaceEnergy peratomtypepair 1 0.1"
            )
        )
    with pytest.raises(engine.ParameterError, match="edinburgh/stiffness"):
        from_liggghts(to_liggghts(LAWS[0]).replace("edinburgh/stiffness", "hertz"))
    with pytest.raises(engine.ParameterError, match="pullOffForce"):
        from_liggghts("\n".join(x for x in to_liggghts(LAWS[0]).splitlines() if "pullOff" not in x))
    rows = law_table(LAWS[1])
    assert rows[0] == {"name": "type", "value": "EEPA", "unit": "", "doc": "contact law"}
    assert {"name": "k1", "value": 5e5, "unit": "N/m^n"} == {
        k: v for k, v in rows[1].items() if k != "doc"
    }
    csv = law_table(LAWS[1], "csv").splitlines()
    assert csv[0] == "name,value,unit,doc" and csv[2].startswith("k1,500000.0,N/m^n,")


def _demscale_rebound(law, v=0.5, r=2.5e-3, dt=1e-6, steps=20000):
    sc = engine.Scene(
        np.array([[-1.2 * r, 0.0, 0.0], [1.2 * r, 0.0, 0.0]]),
        np.array([r, r]),
        2000.0,
        velocities=np.array([[v, 0, 0], [-v, 0, 0]]),
        pair_law=law,
        gravity=(0.0, 0.0, 0.0),
    )
    sim = engine.Simulation(sc, dt=dt)
    sim.run(steps)
    return float(sim.velocities[0, 0])


def _liggghts_rebound(law, tmp_path, v=0.5) -> float:
    deck = f"""units si
atom_style granular
atom_modify map array
boundary f f f
newton off
communicate single vel yes
region box block -0.05 0.05 -0.05 0.05 -0.05 0.05 units box
create_box 1 box
neighbor 0.002 bin
neigh_modify delay 0
fix m1 all property/global youngsModulus peratomtype 1e8
fix m2 all property/global poissonsRatio peratomtype 0.25
{to_liggghts(law)}
create_atoms 1 single -0.003 0 0 units box
create_atoms 1 single 0.003 0 0 units box
set atom 1 diameter 0.005 density 2000 vx {v!r}
set atom 2 diameter 0.005 density 2000 vx {-v!r}
fix integr all nve/sphere
timestep 1e-6
variable v1 equal vx[1]
thermo_style custom step v_v1
thermo_modify format float %.12g
thermo 20000
run 20000
"""
    (tmp_path / "in.law").write_text(deck)
    proc = subprocess.run(
        ["liggghts", "-in", "in.law", "-log", "log.law"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stdout[-3000:]
    rows = re.findall(r"^\s*20000\s+(\S+)\s*$", proc.stdout, re.M)
    assert rows, proc.stdout[-3000:]
    return float(rows[-1])


@pytest.mark.skipif(shutil.which("liggghts") is None, reason="needs Debian's liggghts")
def test_liggghts_runs_the_exported_fragment_as_demscale_does(tmp_path):
    # a head-on impact of two 2.5 mm spheres at 1 m/s: the rebound speed of the exported
    # adhesive law in LIGGGHTS is demscale's (n = 1: the same law, damping included)
    law = LAWS[0]
    lig, ours = _liggghts_rebound(law, tmp_path), _demscale_rebound(law)
    assert lig < 0 and ours < 0  # both rebound
    assert lig == pytest.approx(ours, rel=0.01), (lig, ours)
    # without adhesion the fragment says where the codes part (LIGGGHTS' limitForce), and
    # they do: LIGGGHTS' pair leaves faster, demscale's damping holds it
    plain = engine.BilinearAdhesive(k1=5e3, k2=5e4, kt_ratio=1.0)
    assert any(d.startswith("separation") for d in differences(plain))
    lig, ours = _liggghts_rebound(plain, tmp_path), _demscale_rebound(plain)
    assert lig < ours <= 0, (lig, ours)


@pytest.mark.skipif(shutil.which("liggghts") is None, reason="needs Debian's liggghts")
def test_liggghts_runs_an_exported_adhesive_branch_as_demscale_does(tmp_path):
    # a head-on impact at 2 m/s a sphere, unloading monotonically through the adhesive
    # branch (the codes' forces are the same there: engine.io.liggghts), f0 = 0 so that
    # LIGGGHTS' limitForce would clip the branch if the fragment left it on; 1e-6 relative
    # for two codes of the same arithmetic in another order (measured: 11 digits alike)
    law = engine.BilinearAdhesive(k1=5e3, k2=2.5e4, kadh=500.0, kt_ratio=1.0, restitution=0.9)
    lig, ours = _liggghts_rebound(law, tmp_path, v=2.0), _demscale_rebound(law, v=2.0)
    assert lig == pytest.approx(ours, rel=1e-6), (lig, ours)
    # and the branch acted: without it the pair leaves faster
    assert ours < 0 and abs(ours) < 0.9 * abs(_demscale_rebound(replace(law, kadh=0.0), v=2.0))
