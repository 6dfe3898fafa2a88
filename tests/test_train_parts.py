"""benchmarks/micro/train_parts.py (where a training step's time goes): its timing marks leave the
trainer's step unchanged and split it into parts that add up; its report section computes the rest from the rows."""

import json
import sys
from pathlib import Path

import pytest
import torch

from hcmt.training.trainer import Trainer

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))
import report_common  # noqa: E402
from micro.train_parts import median_row, timed_steps  # noqa: E402
from speed.report import train_parts  # noqa: E402


@pytest.mark.slow  # two tiny trainers, a few eager steps each
def test_timed_steps_change_nothing_and_their_parts_add_up(impact_data, tmp_path, tiny_config):
    cfg = tiny_config("train.steps=6", "train.compile=none")
    runs = [
        Trainer(cfg, impact_data, "hcmt", tmp_path / name, seed=0, resume=False, device="cpu", progress=False)
        for name in ("plain", "timed")
    ]
    loaders = [tr._loader(6) for tr in runs]
    for tr, loader in zip(runs, loaders):
        tr.model.train()
        for _ in range(2):  # the normalizer warm-up and a first update, unmarked
            tr.step(*next(loader))
    for _ in range(4):
        runs[0].step(*next(loaders[0]))
    parts = timed_steps(runs[1], loaders[1], 4)
    assert runs[1].step_count == runs[0].step_count == 6
    for a, b in zip(runs[0].model.parameters(), runs[1].model.parameters()):
        assert torch.equal(a, b)  # the marks change no result
    assert "_update" not in vars(runs[1]) and "step" not in vars(runs[1].opt)  # the class's methods again
    assert all(parts[k] > 0 for k in ("batch", "forward_loss", "backward", "adam", "step"))
    inner = parts["batch"] + parts["forward_loss"] + parts["backward"] + parts["adam"]
    assert inner <= 1.5 * parts["step"] and inner >= 0.5 * parts["step"]  # medians of parts: about the step


def test_report_gives_each_rows_rest_and_the_matmul_share(monkeypatch):
    rows = [
        {
            "recipe": "cpu",
            "threads": 1,
            "step": 50.0,
            "batch": 5.0,
            "forward_loss": 20.0,
            "backward": 22.0,
            "adam": 3.0,
            "profiled_step_ms": 60.0,
            "matmul_ms": 21.0,
            "matmul_calls": 237,
            "matmul_gflops": 101.0,
            "inductor_kernels_ms": 15.0,
            "inductor_kernel_calls": 205,
        },
        {
            "recipe": "ship",
            "threads": 1,
            "step": 60.0,
            "batch": 9.0,
            "forward_loss": 20.0,
            "backward": 24.0,
            "adam": 3.0,
            "profiled_step_ms": 80.0,
            "matmul_ms": 36.0,
            "matmul_calls": 300,
            "matmul_gflops": 99.0,
            "inductor_kernels_ms": 20.0,
            "inductor_kernel_calls": 250,
        },
    ]
    d = {"command": "python benchmarks/micro/train_parts.py --data d", "cpu": "Xeon", "rows": rows}
    monkeypatch.setattr(report_common, "load", lambda name: json.loads(json.dumps(d)) if "parts" in name else None)
    lines = []
    train_parts(lines)
    text = "\n".join(lines)
    assert "| 21.0 (237) | 101 | 15.0 (205) | 14.0 |" in text  # rest = the step 50 - 21 - 15
    assert "| 36.0 (300) | 99 | 20.0 (250) | 4.0 |" in text
    assert "take 51 % of the step at 100 GFLOP/s" in text  # medians of 42 % and 60 %, of 101 and 99
    assert "fused kernels (gathers, scatters, layer norms, the attention's exponentials) 32 %" in text  # 30 %, 33 %
    assert "did not record the core's peak" in text
    assert "What 2× would need" not in text  # no train_speed result beside it
    d["core_peak"] = {"gflops": 150.0, "derivation": "2 FMA units x 16 fp32 lanes"}
    lines = []
    train_parts(lines)
    assert "fp32 peak of 150 GFLOP/s (2 FMA units x 16 fp32 lanes) the matrix products run at 67 %" in "\n".join(lines)
    monkeypatch.setattr(report_common, "load", lambda name: None)
    lines = []
    train_parts(lines)
    assert lines == []  # no result file: no section


def test_a_rows_rounds_give_each_numbers_median():
    rounds = [
        {"recipe": "cpu", "threads": 1, "step": s, "batch": b, "matmul_calls": 237.0}
        for s, b in ((50.0, 5.0), (70.0, 4.0), (52.0, 9.0))
    ]
    row = median_row(rounds)
    assert row["step"] == 52.0 and row["batch"] == 5.0 and row["matmul_calls"] == 237.0  # each field on its own
    assert row["recipe"] == "cpu" and row["threads"] == 1 and row["rounds"] == 3
    assert row["step_by_round"] == [50.0, 70.0, 52.0]


def test_what_2x_would_need_is_half_the_old_step_less_the_kernels():
    from speed.report import two_x_floor

    parts = {
        "commit": "abc1234",
        "rows": [
            {
                "recipe": "cpu",
                "threads": 2,
                "step": 45.0,
                "batch": 4.4,
                "adam": 2.5,
                "matmul_ms": 13.5,
                "inductor_kernels_ms": 16.0,
            },
            {
                "recipe": "ship",
                "threads": 2,
                "step": 45.0,
                "batch": 11.0,
                "adam": 2.5,
                "matmul_ms": 14.5,
                "inductor_kernels_ms": 12.8,
            },
        ],
    }
    runs = [("cpu", 72.0), ("cpu", 74.0), ("ship", 67.6), ("new", 40.0)]
    speed = {
        "commits": {"old": "c18f6a3", "new": "def5678"},
        "summary": [{"recipe": "cpu", "threads": 2}, {"recipe": "ship", "threads": 2}],
        "rows": [
            {
                "side": "new" if r == "new" else "old",
                "recipe": "cpu" if r == "new" else r,
                "threads": 2,
                "ms_per_step": ms,
            }
            for r, ms in runs
        ],
    }
    lines = []
    two_x_floor(lines, parts, speed)
    text = "\n".join(lines)
    # cpu: old median 73.0 -> 36.5 allowed; kernels 13.5 + 16.0 + 2.5 = 32.0; left 4.5 of a rest of 13.0 (35 %)
    assert "| `impact_plate_cpu` defaults | 2 | 73.0 | 36.5 | 45.0 | 32.0 | 4.5 | 13.0 | 35 % |" in text
    assert "| the shipped model's recipe | 2 | 67.6 | 33.8 | 45.0 | 29.8 | 4.0 | 15.2 | 26 % |" in text
    # the batch is all graph building only without pushforward: 4.50 ms left is above its 4.40 ms, so no sentence
    assert "less than building the batch alone" not in text
    parts["rows"][0]["batch"] = 4.6
    lines = []
    two_x_floor(lines, parts, speed)
    text = "\n".join(lines)
    assert (
        "on 2 threads the goal leaves 4.50 ms for everything outside the kernels, less than building the batch "
        "alone takes (4.60 ms)" in text
    )
    assert text.count("less than building") == 1  # not the shipped recipe: its batch includes a forward
    assert "(train_speed at def5678, train_parts at abc1234)" in text
