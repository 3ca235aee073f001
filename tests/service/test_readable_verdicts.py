"""Numbers a person can read (issue 53 item 6): an interval with an end beyond +-1000 % (a
two-seed study's one-degree-of-freedom t interval reaches +1e5 %) or none is printed as
unbounded, in the verdict's reason (the summary's and the reports' text) and on the study
page, whose verdicts are a table (radius x rule x metric, coloured by verdict, the
interval under each error and on hover), not a paragraph. Made-up judgements of the
engine's own judge (two seeds a side), the page's template rendered from them; no run."""

from __future__ import annotations

import re
import uuid
from types import SimpleNamespace

import numpy as np

from engine.study import judge
from engine.study.reasons import UNBOUNDED_WORDS, describe, interval_words, pct
from engine.study.report import StudyReport
from service.models import TERMINAL, Status, Study
from service.routes.studies import public
from service.web import cell, report_tables, templates

#: A per cent figure as the reports print it ("+145 %", "-13.2 %", "above +1000 %" aside).
PERCENT = re.compile(r"(?<![\w.])([+-]?\d[\d.]*(?:e[+-]?\d+)?)\s?%")


def seeds(name: str, values) -> list[dict]:
    return [{name: np.array([v])} for v in values]


def judged() -> list[dict]:
    """Two seeds a side: a loading stiffness whose 1-dof interval runs to about +1e5 %, a
    density with a readable interval, a strength that differs."""
    return [
        judge.judge_values(
            "density", seeds("density", [0.601, 0.604]), seeds("density", [0.6, 0.602]), 0.03, 2e4
        ),
        judge.judge_values(
            "loading_stiffness",
            seeds("loading_stiffness", [1.0, 4.0]),
            seeds("loading_stiffness", [0.9, 1.2]),
            0.15,
            2e4,
        ),
        judge.judge_values(
            "strength", seeds("strength", [5e3, 5.1e3]), seeds("strength", [1e4, 1.01e4]), 0.15, 2e4
        ),
    ]


def no_number_beyond_1000_percent(text: str) -> None:
    for number in PERCENT.findall(text):
        assert abs(float(number)) <= 1000, f"{number} % in: {text[:300]}"


def test_an_unbounded_interval_is_said_so_in_the_reason():
    metrics = judged()
    stiffness = metrics[1]
    assert max(abs(x) for x in stiffness["interval"]) > 100  # beyond +-10,000 %: the case
    overall, reason = judge.verdict(metrics)
    assert overall == "differs"
    line = describe(stiffness)
    assert UNBOUNDED_WORDS.removesuffix(")") in line and "1.0 dof" in line, line
    no_number_beyond_1000_percent(line)
    no_number_beyond_1000_percent(reason)
    assert interval_words([-0.132, -0.011]) == "[-13.2 %, -1.1 %]"
    assert interval_words([-0.99, 4431.4]) == interval_words(None) == UNBOUNDED_WORDS
    # sensible figures: a decimal below 100 %, whole per cent up to 1000 %, words beyond
    assert (pct(0.073), pct(1.449), pct(-0.132)) == ("+7.3 %", "+145 %", "-13.2 %")
    assert pct(4431.4) == "above +1000 %" and pct(float("nan")) == "undefined"


def page(summary: dict) -> str:
    """The study page of a succeeded study with ``summary``, as service.web renders it."""
    row = Study(
        id=uuid.uuid4(),
        name="two seeds",
        spec={"reference": {"type": "UniaxialTest"}, "controls": False},
        status=Status.succeeded,
        progress=1.0,
        n_runs=4,
    )
    report = StudyReport.from_dict(summary["advisor"])
    context = {
        "request": SimpleNamespace(scope={}),
        "study": public(row),
        "runs": [],
        "summary": summary,
        "report": report,
        "missing": None,
        "headings": [],
        "table": [],
        "verdicts": report_tables(report),
        "plots": {},
        "terminal": TERMINAL,
        "fmt": cell,
        "snapshots": {},
    }
    return templates.get_template("study.html").render(context)


def test_the_page_shows_the_verdicts_as_a_table_with_readable_intervals():
    metrics = judged()
    overall, reason = judge.verdict(metrics)
    summary = {
        "table": [],
        "failed": {},
        "advisor": {
            "confidence": 0.95,
            "tolerances": {"density": 0.03, "loading_stiffness": 0.15, "strength": 0.15},
            "message": "R = 3.1 mm, paper: differs",
            "verdicts": [
                {
                    "radius": 3.1e-3,
                    "rule": "paper",
                    "verdict": overall,
                    "reason": reason,
                    "to_decide": None,
                    "seeds": 2,
                    "speedup": 1.9,
                    "metrics": metrics,
                }
            ],
            "resolution_curve": {
                "metrics": {
                    "strength": {
                        "reference_diameters_across": 10.0,
                        "reference_offset": -0.25,
                        "reference_offset_interval": [-0.99, 3.4e25],
                        "sizes": [{"diameters_across": 10.0}, {"diameters_across": 6.7}],
                        "linear": True,
                    }
                }
            },
        },
    }
    html = page(summary)
    verdicts = html[html.index("<h2>Verdicts</h2>") : html.index("<h2>Runs</h2>")]
    table = re.search(r'<table class="verdicts">.*?</table>', verdicts, re.S)
    assert table, verdicts[:2000]
    heads = re.findall(r"<th>(.*?)(?:<br>.*?)?</th>", table[0])
    assert heads[:5] == ["R [mm]", "rule", "verdict", "seeds", "speed-up"]
    assert heads[5:] == ["density", "loading stiffness", "strength"]
    # a cell per metric, coloured by the metric's own verdict, its interval under the
    # error and on hover
    cell_html = r'<td class="num cell-(\w+)" title="([^"]*)">([^<]*)<br><span class="interval">'
    cells = re.findall(cell_html + r"([^<]*)</span>", table[0])
    assert [c[0] for c in cells] == [m["verdict"] for m in metrics]
    assert cells[1][3] == UNBOUNDED_WORDS and "1.0 dof" in cells[1][1]
    assert cells[0][3].startswith("[") and cells[0][2].endswith(" %")
    # the reasons behind "why", a line per metric; the report's paragraph folded away
    assert re.search(
        r"<details><summary>why</summary>\s*<ul>(<li>.*?</li>){3}</ul>", table[0], re.S
    )
    outside = re.sub(r"<details.*?</details>", "", verdicts, flags=re.S)
    assert "R = 3.1 mm, paper: differs" not in outside
    # the resolution curve's unbounded interval, and nowhere a bound beyond +-1000 %
    assert f"<td>{UNBOUNDED_WORDS}</td>" in html
    no_number_beyond_1000_percent(re.sub(r"<[^>]+>", " ", html))
