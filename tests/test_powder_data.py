"""The real powder's shear data (issue 41 item 6; docs/POWDER_DATA.md): the example file
examples/calibration/calcium_carbonate_ring_shear.json loads as LabTargets, holds exactly
the values of the doc's transcription table (each one as printed in the source), names its
source, and carries the uncertainties the doc's rules give (recomputed here from the
transcribed values: the source states none)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from engine.calibration import LabTargets

ROOT = Path(__file__).resolve().parent.parent
FILE = ROOT / "examples" / "calibration" / "calcium_carbonate_ring_shear.json"
DOC = ROOT / "docs" / "POWDER_DATA.md"
SOURCE = (
    "SauretLab/ShearCell",
    "Shear Cell Data/40-200-CaCO3.txt",
    "aef9e4c9d6e85613a3e0877bbc59395548bec4e8",
)
#: the doc's table header (the columns read below)
HEADER = "| level | sigma_p [Pa] | tau_p [Pa] | sigma_S [Pa] | tau_y [Pa] |"


def doc_rows() -> list[tuple[int, float, float, float, float]]:
    """(level, sigma_p, tau_p, sigma_S, tau_y) of each row of the doc's transcription
    table, as written there."""
    lines = DOC.read_text().splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith(HEADER))
    rows = []
    for line in lines[start + 2 :]:  # past the header and its |---| line
        if not line.startswith("|"):
            break
        cells = [c.strip() for c in line.strip("|").split("|")]
        rows.append((int(cells[0]), *(float(c) for c in cells[1:5])))
    return rows


@pytest.fixture(scope="module")
def raw() -> dict:
    return json.loads(FILE.read_text())


def test_the_file_loads_and_holds_exactly_the_doc_transcription(raw):
    targets = LabTargets.from_dict(raw)
    assert targets.resolved_shear_tester() == "ring_shear"
    in_file = [
        (i + 1, locus.sigma_pre, locus.tau_pre, p.sigma_n, p.tau)
        for i, locus in enumerate(targets.shear)
        for p in locus.points
    ]
    rows = doc_rows()
    assert len(rows) == 9  # 3 pre-shear levels, 3 shear-to-failure points each
    assert in_file == rows


def test_the_file_names_its_source_and_says_it_is_a_real_measurement(raw):
    text = raw["material"]
    assert text.startswith("REAL MEASUREMENT, transcribed (docs/POWDER_DATA.md)")
    doc = DOC.read_text()
    for part in SOURCE:
        assert part in text and part in doc, part
    # the source's own verdict travels with the data
    assert "NOT cohesive" in text


def test_the_uncertainties_are_the_stated_rules_applied_to_the_transcribed_values(raw):
    loci = raw["shear"]
    # tau_sd = s_rel tau: s_rel the pooled rms of the relative residuals of each locus's
    # least-squares line (sum of n - 2 = 3 degrees of freedom)
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
    assert f"tau_sd = {s_rel:.4f} tau" in raw["material"]
    assert f"tau_pre_sd = {s_ratio:.4f} sigma_pre" in raw["material"]
    for locus in loci:
        # stored to 0.1 Pa
        assert locus["tau_pre_sd"] == pytest.approx(s_ratio * locus["sigma_pre"], abs=0.05)
        for p in locus["points"]:
            assert p["tau_sd"] == pytest.approx(s_rel * p["tau"], abs=0.05)
            assert p["sigma_n_sd"] == 0.0
        assert "bulk_density" not in locus  # left out: no uncertainty in the source
