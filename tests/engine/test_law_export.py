"""Each law exports itself (engine/contact/export.py): the LIGGGHTS text the exporters write
from the laws' declared mappings is, byte for byte, the text they wrote when they tested the
law's type themselves (tests/data/liggghts/law_export.json, written by the exporters before
the mappings moved into the law modules); a law without a mapping is refused naming the
field; the exporters test no law's type."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import engine
from engine.contact.export import LiggghtsPair
from engine.io import liggghts as lg
from engine.io import liggghts_deck as ld
from tests.engine.toy_law import PowerSpring
from tests.test_liggghts_deck import tiny_test as tiny

EXPECTED = Path(__file__).resolve().parents[1] / "data" / "liggghts" / "law_export.json"

B, E, H = engine.BilinearAdhesive, engine.EEPA, engine.HertzMindlin
LAWS = {
    "bilinear": B(k1=5e3, k2=2.5e4, f0=-0.2),
    "bilinear_kadh": B(k1=5e3, k2=2.5e4, f0=-0.2, kadh=2.5e3, kt_ratio=1.0),
    "bilinear_elastic": B(k1=5e3, k2=5e3, mu_r=0.0, restitution=0.5),
    "eepa": E(k1=5e5, k2=2.5e6, f0=-0.8, n=1.5, chi=1.5, friction_cap="normal"),
    "eepa_2": E(k1=2e4, k2=1e5, f0=-0.4, n=1.2, chi=2.0, restitution=0.6, mu_r=0.0),
    "eepa_linear_kadh": E(
        k1=5e3, k2=2.5e4, f0=-0.1, kadh=1e3, n=1.0, chi=1.0, kt_ratio=1.0, friction_cap="normal"
    ),
}
HERTZ = H(E=1e8, nu=0.3, mu=0.4, mu_r=0.01)


def decks() -> dict[str, engine.UniaxialTest]:
    w = engine.preset("quick").wall_law
    return {
        "tiny": tiny(),
        "plastic": tiny(pair_law=B(k1=5e3, k2=2.5e4, f0=-0.8, mu_s=0.5, mu_r=0.001)),
        "kadh": tiny(pair_law=LAWS["bilinear_kadh"]),
        "eepa": tiny(pair_law=LAWS["eepa"]),
        "eepa_2": tiny(pair_law=LAWS["eepa_2"]),
        "eepa_linear_kadh": tiny(pair_law=LAWS["eepa_linear_kadh"]),
        "hertz": tiny(pair_law=H(E=w.E, nu=w.nu, mu=0.4), pour_speed=0.5),
        "hertz_roll": tiny(
            pair_law=H(E=w.E, nu=w.nu, mu=0.4, mu_r=0.02),
            wall_law=H(E=w.E, nu=w.nu, mu=0.3, mu_r=0.01),
        ),
    }


def outputs() -> dict:
    """What the exporters write for every law and deck of this file."""
    out = {}
    for name, law in LAWS.items():
        out[f"fragment/{name}"] = lg.to_liggghts(law, note="line one\nline two", radius=2.5e-3)
        out[f"differences/{name}"] = lg.differences(law)
    for name, law in {**LAWS, "hertz": HERTZ}.items():
        out[f"table_csv/{name}"] = lg.law_table(law, "csv")
    for name, t in decks().items():
        radii = np.array([t.radius, t.radius * (1 + t.polydispersity)])
        text = ld.deck(t, radii=radii)
        out[f"deck_materials/{name}"] = ld._materials(t)
        out[f"deck_differences/{name}"] = ld.differences(t)
        out[f"deck_law_lines/{name}"] = [
            x for x in text.splitlines() if "pair law" in x or "wall/gran" in x
        ]
    return out


def test_every_law_exports_the_text_it_did():
    expected = json.loads(EXPECTED.read_text())
    got = outputs()
    assert sorted(got) == sorted(expected)
    for key in expected:
        assert got[key] == expected[key], key


def test_each_law_declares_its_mapping():
    for law in (*LAWS.values(), HERTZ):
        pair = law.liggghts()
        assert isinstance(pair, LiggghtsPair) and pair.law == type(law).__name__
        assert [p.name for p in pair.coefficients] == list(lg.PROPERTIES[:3])
    # the adhesive laws: the edinburgh fragment's properties, their exponents n, chi
    eepa = LAWS["eepa"].liggghts()
    assert [p.name for p in (*eepa.coefficients, *eepa.properties)] == list(lg.PROPERTIES)
    props = {p.name: p for p in eepa.properties}
    assert (props["overlapExponent"].value, props["adhesionExponent"].value) == (1.5, 1.5)
    assert props["overlapExponent"].scalar and not props["LoadingStiffness"].scalar
    assert LAWS["bilinear_kadh"].liggghts().settings == " fixKc on limitForce off"
    # the Hertz law: E and nu per atom type, no fragment on its own
    hertz = HERTZ.liggghts()
    assert {p.name: p.value for p in hertz.atom_type} == {
        "youngsModulus": 1e8,
        "poissonsRatio": 0.3,
    }
    assert hertz.model == "hertz" and hertz.fragment


def test_a_law_that_cannot_be_exported_is_refused_naming_the_field():
    with pytest.raises(engine.ParameterError, match=r"^law = 'PowerSpring'") as e:
        lg.to_liggghts(PowerSpring(k=1e3, p=1.5))
    assert "engine.BilinearAdhesive, engine.EEPA or engine.HertzMindlin" in str(e.value)
    with pytest.raises(engine.ParameterError, match=r"UniaxialTest\.pair_law") as e:
        lg.mapping(PowerSpring(k=1e3, p=1.5), "UniaxialTest.pair_law")
    with pytest.raises(engine.ParameterError, match=r"^law = 'HertzMindlin'.*per atom type"):
        lg.to_liggghts(HERTZ)
    with pytest.raises(engine.ParameterError, match=r"^EEPA\.kadh = 10\.0"):
        lg.to_liggghts(E(k1=5e5, k2=2.5e6, kadh=10.0))
    # a Hertz pair law whose nu differs from the wall law's: the field is nu
    w = engine.preset("quick").wall_law
    with pytest.raises(engine.ParameterError, match=r"UniaxialTest\.wall_law\.nu"):
        ld.check_exportable(tiny(pair_law=H(E=w.E, nu=0.2)))


def test_the_exporters_test_no_law_type():
    for module in (lg, ld):
        source = Path(module.__file__).read_text()
        assert "isinstance(" not in source, module.__name__
    # the deck's module does not import a law at all
    assert "from ..contact" not in Path(ld.__file__).read_text()


if __name__ == "__main__":  # regenerate the expected text after a deliberate change
    EXPECTED.write_text(json.dumps(outputs(), indent=1, sort_keys=True) + "\n")
    print(f"wrote {EXPECTED}")
