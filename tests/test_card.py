"""docs/MODELS.md's measured card blocks (benchmarks/release/card.py, written by benchmarks/report.py): the numbers come
from the model's result file, the judgement and the response surface appear only where they measured this model,
the text outside the markers is kept, and a rewrite of an unchanged result is the same text."""

import copy
import json
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))
import release.card as card_module  # noqa: E402
from release.card import begin, card, end, measured_this, training_designs, write_cards  # noqa: E402

RESULTS = ROOT / "benchmarks" / "results"


@pytest.fixture
def model():
    """The shipped model's result file (ship_model.py's layout), renamed and with its step and designs set."""
    m = json.loads((RESULTS / "model_impact_plate_small.json").read_text())
    m["card"]["training_designs"], m["card"]["checkpoint"]["step"] = 480, 400000
    return m


def judge_of(model_name: str, step: int, designs: int) -> dict:
    goals = [
        {
            "goal": "peak plate stress error, median %",
            "target": 3.0,
            "at_least": False,
            "hcmt": 2.5,
            "gp": 1.0,
            "hcmt_met": True,
        },
        {
            "goal": "rebound agreement (designs, at least)",
            "target": 29,
            "at_least": True,
            "hcmt": 28,
            "gp": None,
            "hcmt_met": False,
        },
    ]
    return {
        "model": model_name,
        "checkpoint_step": step,
        "training_designs": designs,
        "goals": goals,
        "seeds": {"in_range": 8101, "outside": 8102},
        "command": "python benchmarks/surrogate/run.py --seed-in 8101",
    }


def test_a_result_measured_this_model_only_with_its_name_designs_and_step(model):
    assert training_designs(model["card"]) == 480
    old = copy.deepcopy(model)
    del old["card"]["training_designs"]  # a file written before the field: from its summary
    old["card"]["summary"] = "HCMT (hidden 64, λ 4, L_C 2) trained 36000 steps on 120 generated `small` Impact Plate"
    assert training_designs(old["card"]) == 120
    assert measured_this(judge_of("pretrained:small", 400000, 480), "small", model)
    assert not measured_this(judge_of("pretrained:small", 120000, 480), "small", model)  # another checkpoint
    assert not measured_this(judge_of("pretrained:small", 400000, 120), "small", model)  # the old model's designs
    assert not measured_this(judge_of("/runs/interim", 400000, 480), "small", model)
    assert measured_this({**judge_of("pretrained:small", 0, 480), "checkpoint_step": None}, "small", model)
    assert not measured_this(None, "small", model)


def test_the_block_quotes_the_result_files(model):
    lines = card("small", model, judge_of("pretrained:small", 400000, 480), None)
    text = "\n".join(lines)
    assert lines[0] == begin("small") and lines[-1] == end("small")
    v = model["verify"]["physics"]
    assert f"| peak plate stress error, median / worst | {v['peak_plate_stress_error_pct']['median_abs']:.1f} %" in text
    assert f"trained {model['card']['steps']} steps" in text and "the weights of step 400,000" in text
    for r in model["card"]["confidence"]:
        assert f"| {r['label']} | {r['designs']} | {r['peak_plate_stress_error_pct_median']:.1f} % / " in text
    weak = max(model["card"]["confidence"], key=lambda r: r["peak_plate_stress_error_pct_median"])
    assert f'is in the region "{weak["label"]}"' in text
    assert "it meets 1 of 2." in text and "| rebound agreement (designs, at least) | ≥ 29 | 28 | no | - |" in text
    assert "**Beside the response surface**: not measured for this model (surrogate.json measured nothing)" in text
    other = "\n".join(card("small", model, judge_of("/runs/interim", 120000, 480), None))
    assert "this model is not judged; model_judge.json judged `/runs/interim` (step 120,000" in other


def test_write_cards_replaces_only_the_blocks_it_has_results_for(model, tmp_path, monkeypatch):
    files = {"model_small.json": model, "model_judge.json": judge_of("pretrained:small", 400000, 480)}
    monkeypatch.setattr(card_module, "load", lambda name: files.get(name))
    doc = tmp_path / "MODELS.md"
    doc.write_text(
        "# Models\n\nhand-written\n\n<!-- card small -->\nold numbers\n<!-- /card small -->\n\nafter\n\n"
        "<!-- card none -->\nkept\n<!-- /card none -->\n"
    )
    assert write_cards(doc) == ["small"]
    text = doc.read_text()
    assert text.startswith("# Models\n\nhand-written\n\n" + begin("small")) and text.endswith(
        "\n\nafter\n\n<!-- card none -->\nkept\n<!-- /card none -->\n"
    )
    assert "old numbers" not in text and "it meets 1 of 2." in text
    assert write_cards(doc) == ["small"] and doc.read_text() == text  # the same results: the same text


def test_the_committed_cards_and_the_readme_quote_the_result_files_as_they_are():
    """docs/MODELS.md's blocks are what report.py writes from today's result files, and the README's headline rows on
    the shipped model quote the same files: a new model's results cannot land with an old card or front door."""
    doc = ROOT / "docs" / "MODELS.md"
    text = doc.read_text()
    for line in text.splitlines():
        if line.startswith("<!-- card "):
            name = line.split()[2].rstrip(":")
            m = card_module.load(f"model_{name}.json")
            block = "\n".join(
                card(
                    name,
                    m,
                    card_module.load("model_judge.json"),
                    card_module.load("surrogate.json"),
                    card_module.load("trust.json"),
                )
            )
            assert block in text, f"docs/MODELS.md's card {name} is stale: run python benchmarks/report.py"
    m, surrogate = card_module.load("model_impact_plate_small.json"), card_module.load("surrogate.json")
    p, n = m["verify"]["physics"], m["verify"]["designs"]
    readme = (ROOT / "README.md").read_text()
    pct = "{median_abs:.1f} % / {worst:.1f} %"
    assert (
        f"| shipped model on {n} held-out designs: rebound agreement | {round(p['rebound_agreement'] * n)} / {n} |"
        in readme
    )
    for label, key in (
        ("peak plate stress", "peak_plate_stress_error_pct"),
        ("max deflection", "max_deflection_error_pct"),
    ):
        e = p[key]
        assert (
            f"| shipped model: {label} error, median / worst | "
            + pct.format(median_abs=e["median_abs"], worst=abs(e["worst"]))
            + " |"
            in readme
        )
    gp = surrogate["accuracy"]["in_range"]["peak_plate_stress_mpa"]["gp"]
    assert (
        f"| response surface on the same {surrogate['training_designs']} solver runs: peak plate stress, median / "
        f"worst | {gp['median_abs_pct']:.1f} % / {gp['worst_abs_pct']:.1f} % |"
    ) in readme
    regions = card_module.load("trust.json")["coverage"]["pooled"]["by_region"]
    got = [
        (regions[k]["coverage"]["peak_plate_stress_mpa"], regions[k]["median_rel_width_peak"])
        for k in ("inside", "outside")
    ]
    assert (" | " + ", ".join(f"{c['covered']} / {c['of']} ({100 * w:.0f} %)" for c, w in got) + " |") in readme


def test_a_shipped_model_reports_the_step_of_its_weights():
    """The judge records ``Run.checkpoint_step`` and the card matches it to the step of the weights shipped (a kept
    checkpoint before the schedule's end), not the schedule's length."""
    import torch

    from hcmt.data.runs import available_pretrained
    from hcmt.inference.run import Run

    pack = torch.load(available_pretrained()["impact_plate_small"], weights_only=True)
    run = Run.load("pretrained:impact_plate_small", "cpu")
    assert run.checkpoint_step == pack["card"]["checkpoint"]["step"]
    shipped = json.loads((RESULTS / "model_impact_plate_small.json").read_text())
    assert run.checkpoint_step == shipped["card"]["checkpoint"]["step"]


def test_the_readme_headline_ratio_is_the_long_schedules_largest_matched_step():
    """The README's HCMT ÷ MGN row quotes scaling_long_run.json at the largest checkpoint step both models reached,
    for the HCMT run the model was shipped from (the second run), with that step named."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from scaling.report import long_run_ratios

    ratios = long_run_ratios(card_module.load("scaling_long_run.json")["checkpoints"])
    last = max(r["step"] for r in ratios)
    (shipped,) = [r for r in ratios if r["step"] == last and r["run"] == "second run"]
    readme = (ROOT / "README.md").read_text()
    assert f"| HCMT ÷ MGN, the shipped model's recipe and 480 designs, at step {last:,} of its 400,000-step" in readme
    assert f"(paper: 0.51 / 0.41) | {shipped['position']:.2f} / {shipped['stress']:.2f} |" in readme
