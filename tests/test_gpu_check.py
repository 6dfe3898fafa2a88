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
    assert list(data["steps"]) == ["cuda tests", "train step", "rollout vs solver", "memory", "deterministic resume",
                                   "accuracy"]
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
