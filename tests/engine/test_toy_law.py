"""A contact law is one unit: a toy law, written in this test and registered, runs in a scene
without any other module knowing it (it reuses the bilinear kernel family's slots)."""

from __future__ import annotations

from dataclasses import dataclass

import pytest

import engine
from engine.contact.limits import TimeStepCandidate, oscillator_limit
from engine.contact.materials import LAWS

from .helpers import pair_scene


@dataclass(frozen=True)
class LinearSpring:
    """A frictionless, undamped linear spring of stiffness ``k`` [N/m]."""

    k: float
    kernel = "bilinear"
    adhesive = False
    pair = True
    wall = False

    def pair_features(self) -> dict[str, bool]:
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
