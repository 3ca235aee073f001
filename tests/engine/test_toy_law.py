"""A contact law is one unit: a toy law of its own force shape (tests/engine/toy_law.py: its
record, scalar kernels and kernel family), registered here, runs in a scene and meets its
closed forms without any other module knowing it; and a law may also stand on an existing
kernel family (a linear spring on the bilinear one)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import pytest

import engine
from engine.contact import bilinear
from engine.contact.limits import TimeStepCandidate, oscillator_limit
from engine.contact.registry import LAWS

from . import toy_law
from .helpers import pair_scene, run_until_separated


@dataclass(frozen=True)
class LinearSpring:
    """A frictionless, undamped linear spring of stiffness ``k`` [N/m]."""

    k: float
    kernel = bilinear.KERNEL
    adhesive = False
    pair = True
    wall = False

    def switches(self) -> dict[str, bool]:
        return {}

    def pair_values(self) -> dict[str, float]:
        return {
            "k1": self.k,
            "k2": self.k,
            "f0": 0.0,
            "kadh": 0.0,
            "kt": 0.0,
            "zeta": 0.0,
            "mu_s": 0.0,
            "mu_r": 0.0,
            "n": 1.0,
            "chi": 1.0,
        }

    def adhesion_overlap(self, rmin: float, fraction: float) -> None:
        return None

    def pair_time_steps(self, m_eff, r_eff, r_min, rho_min, v) -> list[TimeStepCandidate]:
        return [
            TimeStepCandidate(
                "pair", f"toy spring k = {self.k:g} N/m", oscillator_limit(self.k, m_eff, 0.0), True
            )
        ]


@pytest.fixture
def registered(monkeypatch):
    monkeypatch.setitem(LAWS, "LinearSpring", LinearSpring)


def test_a_toy_law_runs_and_matches_the_bilinear_law_it_stands_for(registered):
    toy = engine.Simulation(pair_scene(LinearSpring(k=5e3), v0=0.1), dt=1e-6)
    same = engine.BilinearAdhesive(k1=5e3, k2=5e3, mu_s=0.0, mu_r=0.0, restitution=1.0)
    ref = engine.Simulation(pair_scene(same, v0=0.1), dt=1e-6)
    assert "toy spring" in toy.limit.reason
    toy.run(3000)
    ref.run(3000)
    assert toy.positions.tobytes() == ref.positions.tobytes()
    assert toy.velocities.tobytes() == ref.velocities.tobytes()
    # it did collide, and bounced back elastically
    assert toy.velocities[0, 0] == pytest.approx(-0.1, rel=1e-4)
    with pytest.raises(engine.StabilityError, match="toy spring"):
        engine.Simulation(pair_scene(LinearSpring(k=5e3)), dt=1.0)


def test_an_unregistered_law_is_refused_naming_the_registered_ones():
    with pytest.raises(engine.ParameterError, match="Scene.pair_law.*HertzMindlin"):
        engine.Simulation(pair_scene(LinearSpring(k=5e3)), dt=1e-6)


@pytest.fixture
def power_spring(monkeypatch):
    # the registration: the one change a new law needs outside its module
    monkeypatch.setitem(LAWS, "PowerSpring", toy_law.PowerSpring)
    return toy_law.PowerSpring


@pytest.mark.parametrize("p", [1.0, 3.0])
def test_a_law_of_a_new_force_shape_meets_its_impact_closed_forms(power_spring, p):
    """Two particles meet head-on at 2 v0 under F = k d^p: largest overlap, contact duration
    and rebound speed of the closed forms (energy conservation; restitution 1)."""
    law = power_spring(k=5e3 if p == 1.0 else 5e11, p=p)
    v0, r, rho = 0.1, 2.5e-3, 2000.0
    scene = pair_scene(law, gap=1e-5, v0=v0, radius=r, density=rho)
    limit = engine.critical_time_step(scene)
    assert "power spring" in limit.reason
    # a step fine enough that sampling the peak costs < 1e-3 of it: (w dt)^2 / 8
    sim = engine.Simulation(scene, dt=limit.dt / 50)
    assert sim.features["pair_kernel"] == "power_spring"
    m_star = 0.5 * rho * 4 / 3 * math.pi * r**3
    d_max, _, duration = run_until_separated(sim, 100_000)
    assert d_max == pytest.approx(toy_law.impact_overlap(law.k, p, m_star, 2 * v0), rel=2e-3)
    assert duration == pytest.approx(
        toy_law.impact_duration(law.k, p, m_star, 2 * v0), rel=3 * sim.dt / duration + 1e-3
    )
    # elastic: rebounds at v0, to velocity Verlet's O((w dt)^2) = (2/50)^2
    assert sim.velocities[1, 0] == pytest.approx(v0, rel=(2 / 50) ** 2)
    # a scene's kernel is built for the law's family alone: nothing of another law is in it
    assert set(sim.features) >= {"pair_kernel", "friction", "rolling", "damping"}
    assert "plastic" not in sim.features and "adhesion" not in sim.features


def test_an_unregistered_law_of_a_new_family_is_refused():
    with pytest.raises(engine.ParameterError, match="Scene.pair_law"):
        engine.Simulation(pair_scene(toy_law.PowerSpring(k=5e3)))
