"""The transfer benchmark (benchmarks/transfer/run.py) with a given base model (the shipped
model, fine-tuned at a learning rate of at most 1e-4): end to end on the test run's generated data, the base judged
once, zero-shot and few-shot rows per family, the fine-tuning at the asked rate, the summary in the --json file; and
its docs/RESULTS.md section (benchmarks/transfer/report.py) on a made-up summary of the same shape."""

import json
import shutil
import sys
from pathlib import Path

import pytest
import yaml

from hcmt.training import train

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))
from transfer.report import transfer_given  # noqa: E402
from transfer.run import main as transfer  # noqa: E402


@pytest.mark.slow  # trains a tiny base, fine-tunes it and rolls both out
@pytest.mark.parametrize("kind", ["run", "shipped"])
def test_a_given_base_is_judged_zero_shot_and_fine_tuned_at_the_given_rate(impact_data, tmp_path, tiny_config, kind):
    data = tmp_path / "data"
    shutil.copytree(impact_data, data)
    base = "pretrained:impact_plate_small"
    if kind == "run":
        base = str(tmp_path / "base")
        train(
            tiny_config("train.steps=2", "train.checkpoint_every=2"), data, "hcmt", base, progress=False, device="cpu"
        )
    out = tmp_path / "transfer.json"
    transfer(
        [
            "--work",
            str(tmp_path / "work"),
            "--train-data",
            str(data),
            "--new",
            f"fam={data}",
            "--base",
            f"given={base}",
            "--seeds",
            "0",
            "--shots",
            "5",
            "--ft-steps",
            "2",
            "--ft-lr",
            "1e-4",
            "--eval",
            "1",
            "--json",
            str(out),
        ]
    )
    summary = json.loads(out.read_text())
    rows = summary["rows"]
    assert {"given_base", "given_fam_zero", "given_s0_fam_5", "gp_fam_5", "gp_fam_zero"} <= set(rows)
    assert rows["given_fam_zero"]["designs"] == 1 and rows["given_s0_fam_5"]["designs"] == 1
    assert summary["base"] == f"given={base}" and summary["ft_lr"] == 1e-4
    assert "--ft-lr 0.0001" in summary["command"] and "--models" not in summary["command"]
    assert "--seeds 0 " in summary["command"]  # the seeds of the fine-tunings are part of the command
    ft = yaml.safe_load((tmp_path / "work" / "runs" / "given_s0_fam5" / "run.yaml").read_text())
    assert ft["config"]["train"]["lr"] == 1e-4 and ft["config"]["train"]["lr_final"] == pytest.approx(1e-5)
    assert ft["init"]["from"] == base and ft["init"]["normalizers"] == "keep"
    assert not (tmp_path / "work" / "runs" / "hcmt_s0").exists()  # no base trained


def _summarized(peak: float, deflection: float, mesh: bool = True) -> dict:
    """A row as run.py's ``summarize`` writes it (a GP's lacks the mesh-only keys)."""
    row = {
        "designs": 8,
        "peak": {"median_abs": peak, "worst": -3 * peak},
        "deflection": {"median_abs": deflection, "worst": 2 * deflection},
        "s_per_design": 3.0,
    }
    if mesh:
        row.update(
            {
                "critical_mm": {"median": 0.2, "worst": 0.8},
                "stress_rmse_all": 40e3,
                "rebound_agreement": 0.75,
                "checkpoint_step": 1500,
            }
        )
    return row


def _given_summary(stack3_5: tuple[float, float]) -> dict:
    """A given-base summary: families stack3 and pen, seeds 0 and 1, 5 and 20 runs; stack3's fine-tunings on 5 runs
    have the peak errors ``stack3_5`` (seed 0, seed 1) against a 10 % zero-shot one; pen's on 20 runs were not run."""
    rows = {
        "solver_base": {"s": 8.0},
        "solver_stack3": {"s": 3.0},
        "solver_pen": {"s": 3.1},
        "gp_base": {
            **_summarized(3.0, 0.6, False),
            "fitted_on": 60,
            "parameters": 15,
            "underdetermined": False,
            "cannot_take": [],
        },
        "new_base": _summarized(12.0, 30.0),
    }
    for fam in ("stack3", "pen"):
        rows[f"gp_{fam}_zero"] = {
            "designs": 0,
            "peak": {"median_abs": None, "worst": None},
            "deflection": {"median_abs": None, "worst": None},
            "s_per_design": 0.002,
            "cannot_take": ["layer3_modulus"],
        }
        rows[f"gp_{fam}_5"] = {
            **_summarized(9.0, 20.0, False),
            "fitted_on": 5,
            "parameters": 18,
            "underdetermined": True,
        }
        rows[f"gp_{fam}_20"] = {
            **_summarized(6.0, 0.7, False),
            "fitted_on": 20,
            "parameters": 18,
            "underdetermined": False,
        }
        rows[f"new_{fam}_zero"] = _summarized(10.0, 25.0)
        for seed, peak in enumerate(stack3_5 if fam == "stack3" else (8.0, 6.0)):
            rows[f"new_s{seed}_{fam}_5"] = _summarized(peak, 15.0 + seed)
            if fam == "stack3":
                rows[f"new_s{seed}_{fam}_20"] = _summarized(4.0 + seed, 30.0)
    return {
        "command": "python benchmarks/transfer/run.py --work W --train-data D --new stack3=S --new pen=P "
        "--base new=pretrained:impact_plate_small --ft-steps 1500 --ft-lr 0.0001 --shots 5 20 --eval 8",
        "base": "new=pretrained:impact_plate_small",
        "ft_lr": 1e-4,
        "device": "cpu (x86_64)",
        "train_families": ["mono", "ring", "stack2"],
        "new_families": {"stack3": "S", "pen": "P"},
        "rows": rows,
    }


def _rendered(r: dict | None) -> str:
    lines = []
    transfer_given(lines, r)
    return "\n".join(lines)


def test_the_given_base_section_prints_its_rows_and_judges_the_fine_tuning():
    text = _rendered(_given_summary((14.0, 20.0)))
    assert text.startswith("## Panel families: transfer from a given model")
    assert "**new** (`pretrained:impact_plate_small`)" in text and "learning rate of 1e-4, decaying to 1e-5" in text
    assert "| new | - (given model) | 12.0 / 36.0 |" in text and "| GP | 60 | 3.0 / 9.0 |" in text
    stack3 = text.split("**stack3")[1].split("**pen")[0]
    assert "| new zero-shot | 0 (given model) | 10.0 / 30.0 |" in stack3  # new_stack3_zero's median peak
    assert "| new fine-tuned on 5 | 5 | 17.0 (14.0 / 20.0) / 51.0 (42.0 / 60.0) |" in stack3  # mean (each seed)
    assert "| new fine-tuned on 20 | 20 | 4.5 (4.0 / 5.0) / " in stack3
    assert "| GP fitted on 5 (18 parameters: underdetermined) | 5 | 9.0 / 27.0 |" in stack3
    assert "| solver | every design | 0 | 0 | 0 | 0 | 100 % | 3 |" in stack3
    pen = text.split("**pen")[1]
    assert "| new fine-tuned on 20 | 20 | not run |" in pen
    assert (
        "- new on stack3: 10.0 % zero-shot, 17.0 % after 5 runs, 4.5 % after 20 runs; fine-tuning on 5 runs made "
        "the median peak error worse than none." in stack3
    )
    assert "- new on pen: 10.0 % zero-shot, 7.0 % after 5 runs." in pen and "worse than none" not in pen
    assert (
        "- stack3, 5 runs: the lowest median peak plate stress error is the GP's (9.0 % against new fine-tuned's "
        "17.0 %); the lowest median deflection error is new fine-tuned's (15.5 % against the GP's 20.0 %)." in stack3
    )
    better = _rendered(_given_summary((6.0, 8.0))).split("**pen")[0]
    assert "7.0 % after 5 runs, 4.5 % after 20 runs." in better and "worse than none" not in better


def test_the_given_base_section_says_how_to_run_it_when_not_run():
    text = _rendered(None)
    assert "Not run yet" in text and "--base new=pretrained:impact_plate_small --ft-lr 1e-4" in text
