"""The GPU acceptance script rehearsed on every CI run: `benchmarks/gpu_check/run.py --smoke --device cpu` runs the
whole sequence at toy sizes and writes its JSON as it goes; a budget too small for a step skips it by name; no CUDA:
one line."""

import json
import subprocess
import sys
from pathlib import Path

import pytest
import torch

pytestmark = pytest.mark.slow  # runs a benchmark script

SCRIPT = Path(__file__).resolve().parent.parent / "benchmarks" / "gpu_check" / "run.py"


def _run(*args):
    return subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True, text=True, timeout=300)


def test_smoke_runs_every_step(tmp_path):
    r = _run("--smoke", "--device", "cpu", "--out", str(tmp_path), "--budget-s", "300")
    assert r.returncode == 0, r.stderr[-2000:]
    data = json.loads((tmp_path / "gpu_check.json").read_text())
    assert list(data["steps"]) == [
        "cuda tests",
        "train step",
        "rollout vs solver",
        "memory",
        "deterministic resume",
        "accuracy",
    ]
    errors = {k: v["error"] for k, v in data["steps"].items() if "error" in v}
    assert not errors, errors
    assert data["steps"]["deterministic resume"]["exact"] is True
    modes = {(row["model"], row["mode"]) for row in data["steps"]["train step"]["rows"]}
    assert ("hcmt-official", "eager") in modes and ("mgn", "bf16") in modes
    assert len(data["steps"]["accuracy"]["rows"]) == 4 and "gpu_check on cpu" in r.stdout


def test_a_small_budget_skips_steps_by_name(tmp_path):
    r = _run("--smoke", "--device", "cpu", "--out", str(tmp_path), "--budget-s", "1")
    assert r.returncode == 0
    data = json.loads((tmp_path / "gpu_check.json").read_text())
    assert any(s.startswith("accuracy (needs") for s in data["skipped"]) and "skipped: accuracy" in r.stdout


@pytest.mark.skipif(torch.cuda.is_available(), reason="a CUDA device is present")
def test_no_cuda_is_one_line(tmp_path):
    r = _run("--out", str(tmp_path))
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "--smoke --device cpu" in r.stderr


def test_resume_keeps_finished_steps_and_reruns_failed_ones(tmp_path):
    earlier = {
        "device": "NVIDIA H200",
        "torch": "2.x",
        "budget_s": 490,
        "skipped": [],
        "steps": {
            "cuda tests": {"wall_s": 1.0, "returncode": 0, "lines": ["6 passed"]},
            "train step": {"wall_s": 2.0, "error": "RuntimeError: x"},
        },
    }
    (tmp_path / "gpu_check.json").write_text(json.dumps(earlier))
    r = _run("--smoke", "--device", "cpu", "--out", str(tmp_path), "--budget-s", "1", "--resume")
    assert r.returncode == 0, r.stderr[-2000:]
    data = json.loads((tmp_path / "gpu_check.json").read_text())
    assert data["steps"] == {"cuda tests": earlier["steps"]["cuda tests"]}  # the failed step is not kept
    assert any(s.startswith("train step (needs") for s in data["skipped"])  # ... and is tried again
    assert not any(s.startswith("cuda tests") for s in data["skipped"])
    assert data["earlier_calls"] == [{"device": "NVIDIA H200", "torch": "2.x", "budget_s": 490}]


def _report(monkeypatch, data):
    sys.path.insert(0, str(SCRIPT.parent.parent))
    import gpu_check.report as report

    monkeypatch.setattr(report, "load", lambda name: json.loads(json.dumps(data)))
    lines = []
    report.gpu_check(lines)
    return "\n".join(lines)


def _row(model, mode, batch, ms, inference=None):
    r = {
        "model": model,
        "mode": mode,
        "batch": batch,
        "nodes": 2000 * batch,
        "train_ms": ms,
        "samples_per_s": 1e3 * batch / ms,
    }
    return r | ({"inference_ms": inference} if inference else {})


def test_report_reads_each_goal_from_the_rows(monkeypatch):
    rows = [
        _row("mgn", "eager", 1, 40.0, 10.0),
        _row("mgn", "eager", 32, 30.0),
        _row("mgn", "compile-default", 1, 10.0, 2.5),
        _row("mgn", "compile-reduce-overhead", 1, 11.0, 2.0),
    ]
    data = {
        "device": "NVIDIA H200",
        "torch": "2.x",
        "smoke": False,
        "budget_s": 300,
        "skipped": [],
        "earlier_calls": [{"budget_s": 490}],
        "steps": {
            "train step": {"rows": rows},
            "rollout vs solver": {
                "one_design_s": 0.05,
                "solver_one_design_s": 3.0,
                "speedup_one": 60.0,
                "batch": 64,
                "batch_per_design_s": 0.01,
                "solver": "FEM",
                "solver_designs": 4,
                "solver_median_s": 2.0,
                "speedup_batch": 200.0,
            },
            "memory": {
                "rows": [
                    {
                        "nodes": 240000,
                        "checkpoint_blocks": True,
                        "train_ms": 900.0,
                        "peak_mb": 40960.0,
                        "peak_kb_per_node": 170.0,
                    }
                ]
            },
        },
    }
    text = _report(monkeypatch, data)
    goals = {
        line.split(" | ")[0].lstrip("| "): line
        for line in text.splitlines()
        if line.startswith("| ≥") or line.startswith("| ≤") or line.startswith("| a 250")
    }
    assert goals["≥ 40× for one paper design"].endswith("| yes |")
    assert goals["≥ 400× for a 64-design sweep"].endswith("| no |")
    assert "| 10 | mgn compile-default | yes |" in goals["≤ 12 ms per paper-size train step"]
    assert "| 1,067 | mgn eager batch 32 | yes |" in goals["≥ 1,000 samples/s"]  # 32 / 30 ms
    assert "| 2 | mgn compile-reduce-overhead | yes |" in goals["≤ 3 ms inference"]
    assert "not measured at 250,000" in goals["a 250,000-node step"]
    assert "2 calls (490 s, then 300 s of budget" in text
    assert "mgn 0.8×" in text and "mgn 4.0×" in text and "mgn 1.10×" in text  # batch growth, compile, CUDA graphs


def test_report_without_a_gpu_run_says_not_measured(monkeypatch):
    text = _report(monkeypatch, {"smoke": True})
    assert "has not run on a GPU yet" in text and "**not measured**" in text
