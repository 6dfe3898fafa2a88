"""The transfer benchmark (benchmarks/transfer/run.py) with a given base model (issue 35 item 6: the new shipped
model, fine-tuned at a learning rate of at most 1e-4): end to end on the test run's generated data, the base judged
once, zero-shot and few-shot rows per family, the fine-tuning at the asked rate, the summary in the --json file."""
import json
import shutil
import sys
from pathlib import Path

import pytest
import yaml

from hcmt.training import train

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))
from transfer.run import main as transfer  # noqa: E402

pytestmark = pytest.mark.slow  # trains a tiny base, fine-tunes it and rolls both out


@pytest.mark.parametrize("kind", ["run", "shipped"])
def test_a_given_base_is_judged_zero_shot_and_fine_tuned_at_the_given_rate(impact_data, tmp_path, tiny_config, kind):
    data = tmp_path / "data"
    shutil.copytree(impact_data, data)
    base = "pretrained:impact_plate_small"
    if kind == "run":
        base = str(tmp_path / "base")
        train(tiny_config("train.steps=2", "train.checkpoint_every=2"), data, "hcmt", base, progress=False,
              device="cpu")
    out = tmp_path / "transfer.json"
    transfer(["--work", str(tmp_path / "work"), "--train-data", str(data), "--new", f"fam={data}", "--base",
              f"given={base}", "--seeds", "0", "--shots", "5", "--ft-steps", "2", "--ft-lr", "1e-4",
              "--eval", "1", "--json", str(out)])
    summary = json.loads(out.read_text())
    rows = summary["rows"]
    assert {"given_base", "given_fam_zero", "given_s0_fam_5", "gp_fam_5", "gp_fam_zero"} <= set(rows)
    assert rows["given_fam_zero"]["designs"] == 1 and rows["given_s0_fam_5"]["designs"] == 1
    assert summary["base"] == f"given={base}" and summary["ft_lr"] == 1e-4
    assert "--ft-lr 0.0001" in summary["command"] and "--models" not in summary["command"]
    ft = yaml.safe_load((tmp_path / "work" / "runs" / "given_s0_fam5" / "run.yaml").read_text())
    assert ft["config"]["train"]["lr"] == 1e-4 and ft["config"]["train"]["lr_final"] == pytest.approx(1e-5)
    assert ft["init"]["from"] == base and ft["init"]["normalizers"] == "keep"
    assert not (tmp_path / "work" / "runs" / "hcmt_s0").exists()  # no base trained
