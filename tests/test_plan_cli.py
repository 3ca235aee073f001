"""`demscale plan` (issue 50 item 4): the answer line first, each feature kind's evidence,
bad input refused naming the field (exit 2)."""

from __future__ import annotations

import json

from demscale.cli import main


def test_plan_prints_the_answer_first_then_each_kinds_evidence(capsys):
    rc = main(
        ["plan", "--default-powder", "--diameter", "50e-6", "--width", "0.2", "--stress", "2e4"]
    )
    out = capsys.readouterr().out.splitlines()
    assert rc == 0
    assert out[0].startswith("50 um powder, bulk_shear 200 mm wide at 20 kPa: bulk_shear: s_max")
    assert "matches stored series bond1" in "\n".join(out)
    kinds = [line for line in out if line.startswith("- ")]
    assert [k.split(":")[0] for k in kinds] == [
        "- bulk_shear",
        "- bulk_compression",
        "- free_surface",
        "- outlet",
    ]
    # each kind's line is its plan's words (the stored evidence decides which)
    import engine
    from engine.process import plan_process

    base = engine.default_study().reference
    law = engine.similar(base.pair_law, 50e-6 / (2 * base.radius))
    plan = plan_process(engine.Process(pair_law=law, diameter=50e-6, feature_width=0.2, stress=2e4))
    whys = {f.kind: f.why for f in plan.features}
    for k in kinds:
        kind = k[2:].split(":")[0]
        assert whys[kind] in k


def test_plan_json_and_a_law_file_with_its_radius(tmp_path, capsys):
    law = {
        "type": "BilinearAdhesive",
        "k1": 5e3,
        "k2": 2.5e4,
        "f0": -0.4,
        "reference_radius": 2.5e-3,
    }
    f = tmp_path / "law.json"
    f.write_text(json.dumps(law))
    rc = main(
        [
            "plan",
            "--law",
            str(f),
            "--diameter",
            "1e-4",
            "--width",
            "0.1",
            "--kind",
            "free_surface",
            "--stress",
            "2e4",
            "--json",
        ]
    )
    plan = json.loads(capsys.readouterr().out)
    assert rc == 0 and plan["matched_series"] == "bond1"
    assert plan["features"][0]["kind"] == "free_surface"
    # the law scaled by the similarity to 100 um: k1 x 0.02, f0 x 0.0004
    assert plan["process"]["pair_law"]["k1"] == 100.0


def test_plan_refuses_bad_input_naming_the_field(tmp_path, capsys):
    rc = main(["plan", "--default-powder", "--diameter", "50e-6", "--width", "-0.2"])
    assert rc == 2 and "Process.feature_width" in capsys.readouterr().err
    f = tmp_path / "law.json"
    f.write_text(json.dumps({"type": "HertzMindlin", "E": 1e8}))
    rc = main(["plan", "--law", str(f), "--diameter", "1e-4", "--width", "0.1"])
    assert rc == 2 and "--law" in capsys.readouterr().err
