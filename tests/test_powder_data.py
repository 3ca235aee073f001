"""The real materials' shear data (issue 41 item 6; docs/POWDER_DATA.md): each example
file (examples/calibration/calcium_carbonate_ring_shear.json,
examples/calibration/wet_glass_beads_ring_shear.json) loads as LabTargets, holds exactly the
values of the doc's transcription table for it (each one as printed in the source), names
its source, and carries the uncertainties the doc's rules give (recomputed here from the
transcribed values: the sources state none; one rule for both files)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from engine.calibration import LabTargets

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "POWDER_DATA.md"
#: per file: its source (repository, path, commit), the header of its table in the doc,
#: the number of pre-shear levels and points per level, and the source's verdict on
#: cohesion that its material text must carry
FILES = {
    "calcium_carbonate_ring_shear.json": (
        (
            "SauretLab/ShearCell",
            "Shear Cell Data/40-200-CaCO3.txt",
            "aef9e4c9d6e85613a3e0877bbc59395548bec4e8",
        ),
        "| level | sigma_p [Pa] | tau_p [Pa] | sigma_S [Pa] | tau_y [Pa] |",
        (3, 3),
        "NOT cohesive",
    ),
    "wet_glass_beads_ring_shear.json": (
        (
            "SauretLab/ShearCell",
            "Shear Cell Data/0.5 mm 0.5% Water.txt",
            "09dbe923e8020abaaa9a8e3ff06256b0aec714a7",
        ),
        "| wet beads level | sigma_p [Pa] | tau_p [Pa] | sigma_S [Pa] | tau_y [Pa] |",
        (5, 5),
        "COHESIVE by its tester at 4 of the 5 levels",
    ),
}


def doc_rows(header: str) -> list[tuple[int, float, float, float, float]]:
    """(level, sigma_p, tau_p, sigma_S, tau_y) of each row of the doc's transcription
    table under ``header``, as written there."""
    lines = DOC.read_text().splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith(header))
    rows = []
    for line in lines[start + 2 :]:  # past the header and its |---| line
        if not line.startswith("|"):
            break
        cells = [c.strip() for c in line.strip("|").split("|")]
        rows.append((int(cells[0]), *(float(c) for c in cells[1:5])))
    return rows


def raw(name: str) -> dict:
    return json.loads((ROOT / "examples" / "calibration" / name).read_text())


@pytest.mark.parametrize("name", sorted(FILES))
def test_the_file_loads_and_holds_exactly_the_doc_transcription(name):
    _, header, (levels, per_level), _ = FILES[name]
    targets = LabTargets.from_dict(raw(name))
    assert targets.resolved_shear_tester() == "ring_shear"
    in_file = [
        (i + 1, locus.sigma_pre, locus.tau_pre, p.sigma_n, p.tau)
        for i, locus in enumerate(targets.shear)
        for p in locus.points
    ]
    rows = doc_rows(header)
    assert len(rows) == levels * per_level
    assert [len(locus.points) for locus in targets.shear] == [per_level] * levels
    assert in_file == rows


@pytest.mark.parametrize("name", sorted(FILES))
def test_the_file_names_its_source_and_says_it_is_a_real_measurement(name):
    source, _, _, verdict = FILES[name]
    text = raw(name)["material"]
    assert text.startswith("REAL MEASUREMENT, transcribed (docs/POWDER_DATA.md)")
    doc = DOC.read_text()
    for part in source:
        assert part in text and part in doc, part
    # the source's own verdict travels with the data
    assert verdict in text


def test_the_wet_beads_carry_the_sources_own_cohesion_and_say_what_they_are():
    text = raw("wet_glass_beads_ring_shear.json")["material"]
    # as printed in the source's analysis, level by level
    assert "cohesion 370.7, 0, 484.9, 2168 and 2636 Pa" in text
    assert "ffc 2.3 (cohesive), infinite (free-flowing), 4.91 (easy-flowing)" in text
    assert "MODEL MATERIAL, not a fine powder" in text


@pytest.mark.parametrize("name", sorted(FILES))
def test_the_uncertainties_are_the_stated_rules_applied_to_the_transcribed_values(name):
    loci = raw(name)["shear"]
    # tau_sd = s_rel tau: s_rel the pooled rms of the relative residuals of each locus's
    # least-squares line (sum of n - 2 degrees of freedom)
    num, dof = 0.0, 0
    for locus in loci:
        x = np.array([p["sigma_n"] for p in locus["points"]])
        y = np.array([p["tau"] for p in locus["points"]])
        m, c = np.polyfit(x, y, 1)
        num += float((((y - (m * x + c)) / y) ** 2).sum())
        dof += len(x) - 2
    s_rel = (num / dof) ** 0.5
    # tau_pre_sd = s_ratio sigma_pre: s_ratio the sd of tau_pre / sigma_pre over the levels
    s_ratio = float(np.std([lo["tau_pre"] / lo["sigma_pre"] for lo in loci], ddof=1))
    text = raw(name)["material"]
    assert f"tau_sd = {s_rel:.4f} tau" in text
    assert f"{dof} degrees of freedom" in text
    assert f"tau_pre_sd = {s_ratio:.4f} sigma_pre" in text
    for locus in loci:
        # stored to 0.1 Pa
        assert locus["tau_pre_sd"] == pytest.approx(s_ratio * locus["sigma_pre"], abs=0.05)
        for p in locus["points"]:
            assert p["tau_sd"] == pytest.approx(s_rel * p["tau"], abs=0.05)
            assert p["sigma_n_sd"] == 0.0
        assert "bulk_density" not in locus  # left out: no uncertainty in the source
