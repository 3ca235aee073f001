"""The ring-shear benchmark's deck and stress conversion (benchmarks/annular_shear; docs/SHEAR.md,
"Against a ring shear cell (LIGGGHTS)"). Skipped where LIGGGHTS is not installed."""

from __future__ import annotations

import math
import re
import shutil
import subprocess

import numpy as np
import pytest

import engine
from benchmarks.annular_shear import ring as rg
from engine.io.liggghts import to_liggghts

pytestmark = pytest.mark.skipif(shutil.which("liggghts") is None, reason="liggghts not installed")

LAW = engine.EEPA(
    k1=5e3, k2=2.5e4, f0=0.0, kadh=0.0, n=1.0, chi=1.0, kt_ratio=1.0, mu_s=0.5, mu_r=0.001,
    restitution=0.4, friction_cap="normal",
)  # fmt: skip


def _ring(**kw) -> rg.Ring:
    base = dict(
        law=LAW, radius=2.5e-3, density=2000.0, mean_radius=0.075, width=0.025,
        height=0.075, dt=2.26e-5, servo_gain=9.4e-6,
    )  # fmt: skip
    base.update(kw)
    return rg.Ring(**base)


def test_torque_to_stress_is_the_closed_form():
    """tau = T / (2 pi int_Ri^Ro r^2 dr) = 3 T / (2 pi (Ro^3 - Ri^3)): a uniform stress's
    torque integrated numerically over the annulus comes back as that stress."""
    ri, ro, tau = 0.0625, 0.0875, 3456.0
    r = np.linspace(ri, ro, 200001)
    torque = np.trapezoid(tau * r * 2 * np.pi * r, r)
    assert rg.shear_stress(torque, ri, ro) == pytest.approx(tau, rel=1e-9)
    assert rg.torque_lever(ri, ro) == pytest.approx(2 * math.pi * (ro**3 - ri**3) / 3, rel=1e-15)
    assert rg.normal_stress(10.0, ri, ro) == pytest.approx(10.0 / (math.pi * (ro**2 - ri**2)))
    ring = _ring()
    assert ring.lever == pytest.approx(rg.torque_lever(ring.ri, ring.ro))
    # the report's conversion of a curve row is this one
    from benchmarks.annular_shear.__main__ import _stresses

    c = {"force_lid": np.array([7.0]), "torque_lid": np.array([0.3]), "z_lid": np.array([0.08]),
         "z_base": np.array([0.005])}  # fmt: skip
    sig, t, h = _stresses(c, ring)
    assert t[0] == pytest.approx(0.3 * 3 / (2 * math.pi * (ring.ro**3 - ring.ri**3)))
    assert sig[0] == pytest.approx(7.0 / (math.pi * (ring.ro**2 - ring.ri**2)))
    assert h[0] == pytest.approx(0.075)


def test_packing_fills_the_annulus():
    ring = _ring(mean_radius=0.04, width=0.02, height=0.03)
    p = ring.positions()
    assert len(p) == ring.particles == round(0.6 * ring.area * 0.03 / (4 / 3 * math.pi * 2.5e-3**3))
    r = np.hypot(p[:, 0], p[:, 1])
    assert r.min() > ring.ri + ring.radius and r.max() < ring.ro - ring.radius
    assert p[:, 2].min() > ring.radius
    d = np.linalg.norm(p[:, None, :] - p[None, :, :], axis=-1) + np.eye(len(p))
    assert d.min() > 2 * ring.radius


def test_deck_geometry_servo_and_law():
    ring = _ring()
    deck = ring.preshear_deck()
    ri, ro = ring.ri, ring.ro
    # geometry: frictionless cylinders (type 2) at Ri and Ro about z, the floor (type 3)
    assert f"primitive type 2 zcylinder {ri!r} 0.0 0.0" in deck
    assert f"primitive type 2 zcylinder {ro!r} 0.0 0.0" in deck
    assert "primitive type 3 zplane 0.0" in deck
    assert f"variable area equal {ring.area!r}" in deck
    # the lid: z only, at the servo's speed g (F_z / A - sigma_pre) clipped to +-vcap
    assert "fix servo lid move variable NULL NULL NULL v_zero v_zero v_vzpre" in deck
    assert "(v_gain*(v_fzl/v_area-10000.0))" in deck
    assert f"variable gain equal {ring.servo_gain!r}" in deck
    # the base turns about +z at the mean radius' speed, the lid's torque is sum(x fy - y fx)
    assert f"variable period_rot equal 2*PI*{ring.mean_radius!r}/${{vpre}}" in deck
    assert "fix rot base move rotate 0.0 0.0 0.0 0.0 0.0 1 ${period_rot}" in deck
    assert "variable tqa atom x*fy-y*fx" in deck and "compute tql lid reduce sum v_tqa" in deck
    # the law: to_liggghts's fragment, each pair value widened to three types
    frag = to_liggghts(LAW, radius=ring.radius)
    pair = [ln for ln in frag.splitlines() if ln.startswith("pair_style")]
    assert pair and pair[0] in deck.splitlines()
    f = re.search(r"coefficientFriction peratomtypepair 3 (.*)", deck).group(1).split()
    assert [float(x) for x in f] == [0.5, 0.0, 0.3, 0.0, 0.5, 0.5, 0.3, 0.5, 0.5]
    k = re.search(r"LoadingStiffness peratomtypepair 3 (.*)", deck).group(1).split()
    assert float(k[0]) == 5e3
    point = ring.point_deck(0, 0.07)
    assert "read_restart preshear.restart" in point
    assert "(v_gain*(v_fzl/v_area-2000.0))" in point  # proportional without servo_time
    # demscale's PI servo: T_i = 5 T, the integral only within 10 % of the target
    pi = _ring(servo_time=3e-3).point_deck(0, 0.07)
    assert "variable e_vzs equal v_fzl/v_area-2000.0" in pi
    assert "variable ein_vzs equal v_e_vzs*(abs(v_e_vzs)<200.0)" in pi
    assert "fix ish all ave/time 1 1 1 v_ein_vzs ave running" in pi
    assert "(v_gain*(v_e_vzs+f_ish*step*2.26e-05/0.015))" in pi
    assert "fix servo lid move variable NULL NULL NULL v_zero v_zero v_vzs" in pi
    assert "fix rev base move rotate 0.0 0.0 0.0 0.0 0.0 -1 ${period_rev}" in point
    vn = ring.speed(2000.0, 0.07)
    assert vn == pytest.approx(1e-3 * 0.07 / 5e-3 * math.sqrt(2000.0 / 2000.0))
    assert f"variable vn equal {vn!r}" in point


def test_tiny_ring_runs(tmp_path):
    """A 648-sphere ring through both decks for a few hundred steps: LIGGGHTS takes them and
    every curve file has the benchmark's columns."""
    ring = _ring(
        mean_radius=0.03, width=0.015, height=0.025, settle_time=0.01, consolidation_time=0.01,
        preshear_strain=0.004, normal_time=0.003, failure_strain=0.01, chunk_strain=0.002,
        servo_time=3e-3,
    )  # fmt: skip
    (tmp_path / "ring.data").write_text(ring.data_file())
    (tmp_path / "plate.stl").write_text(ring.plate())
    (tmp_path / "in.preshear").write_text(ring.preshear_deck())
    (tmp_path / "in.point0").write_text(ring.point_deck(0, 0.047))
    for deck in ("in.preshear", "in.point0"):
        done = subprocess.run(
            ["liggghts", "-in", deck, "-log", f"log.{deck}"],
            cwd=tmp_path, timeout=60, capture_output=True,
        )  # fmt: skip
        assert done.returncode == 0, (tmp_path / f"log.{deck}").read_text()[-2000:]
    meta = (tmp_path / "meta.txt").read_text()
    assert "done" in meta and "point 0 done" in meta
    for name in ("preshear", "reverse_0", "normal_0", "shear_0"):
        a = np.loadtxt(tmp_path / f"{name}.txt", comments="#", ndmin=2)
        assert a.shape[1] == len(rg.COLUMNS) and len(a) >= 1 and np.isfinite(a).all()
