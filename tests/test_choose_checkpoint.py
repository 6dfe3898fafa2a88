"""Choosing a long run's checkpoint (benchmarks/release/choose_checkpoint.py): every kept
checkpoint is judged on the validation split with the scaling study's errors, the worst ratio to the goals decides,
and the chosen one loads for shipping; a missing kept step is an error, never silently the latest."""

import json
import shutil
import sys
from pathlib import Path

import pytest
import torch

from hcmt.errors import InputError
from hcmt.inference.run import Run
from hcmt.training import train

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))
from hcmt.data.runs import RunFolder  # noqa: E402
from release.average_checkpoints import average  # noqa: E402
from release.choose_checkpoint import GOALS, choose, kept, score  # noqa: E402

pytestmark = pytest.mark.slow  # trains a tiny run and rolls out its checkpoints


def test_score_is_the_worst_ratio_to_the_goals():
    assert GOALS == {"peak_error_pct": 3.0, "deflection_error_pct": 4.0, "ghost_difference": 0.05}
    assert score({"peak_error_pct": 1.5, "deflection_error_pct": 8.0, "ghost_difference": 0.01}) == 2.0
    assert score({"peak_error_pct": 3.0, "deflection_error_pct": 2.0, "ghost_difference": 0.02}) == 1.0


def test_every_kept_checkpoint_is_judged_on_the_validation_split_and_the_lowest_score_chosen(
    impact_data, tmp_path, tiny_config
):
    data = tmp_path / "data"
    shutil.copytree(impact_data, data)
    cfg = tiny_config(
        "train.steps=3",
        "train.keep_every=1",
        "train.checkpoint_every=1",
        "train.valid_every=1",
        "train.valid_trajectories=1",
    )
    train(cfg, data, "hcmt", tmp_path / "run", progress=False, device="cpu")
    folder = RunFolder(tmp_path / "run")
    assert kept(folder) == ["best", "step_1", "step_2", "step_3"]
    out = choose(tmp_path / "run", data, "valid")
    rows = {r["checkpoint"]: r for r in out["rows"]}
    assert [rows[f"step_{n}"]["checkpoint_step"] for n in (1, 2, 3)] == [1, 2, 3]
    assert all(r["trajectories"] == 1 and r["score"] == score(r["errors"]) for r in rows.values())
    assert out["chosen"] == min(rows.values(), key=lambda r: r["score"])["checkpoint"]
    assert not list((tmp_path / "run").glob("rollout_*.h5"))  # rollouts are not kept
    chosen = Run.load(tmp_path / "run", "cpu", out["chosen"])
    assert chosen.checkpoint_step == out["chosen_step"]
    first = torch.load(tmp_path / "run" / "step_1.pt", weights_only=False)["model"]
    assert not all(
        torch.equal(first[k], v)
        for k, v in torch.load(tmp_path / "run" / "step_3.pt", weights_only=False)["model"].items()
    )
    with pytest.raises(InputError, match="step_9.pt: no such checkpoint"):
        Run.load(tmp_path / "run", "cpu", "step_9")
    json.dumps(out)  # the --json file's content


def test_a_cache_judges_kept_checkpoints_once_and_best_every_time(impact_data, tmp_path, tiny_config, monkeypatch):
    import release.choose_checkpoint as cc

    cfg = tiny_config(
        "train.steps=2",
        "train.keep_every=1",
        "train.checkpoint_every=1",
        "train.valid_every=1",
        "train.valid_trajectories=1",
    )
    train(cfg, impact_data, "hcmt", tmp_path / "run", progress=False, device="cpu")
    judged = []
    real = cc.test_errors

    def counting(loaded, *args):
        judged.append(loaded.checkpoint_step)
        return real(loaded, *args)

    monkeypatch.setattr(cc, "test_errors", counting)
    first = choose(tmp_path / "run", impact_data, "valid", cache=tmp_path / "cache")
    assert sorted(judged) == [1, 2, 2]  # best (step 2), step_1, step_2
    judged.clear()
    again = choose(tmp_path / "run", impact_data, "valid", cache=tmp_path / "cache")
    assert judged == [2]  # only best.pt, which moves while a run trains
    assert again["rows"] == first["rows"] and again["chosen"] == first["chosen"]
    assert sorted(p.name for p in (tmp_path / "cache").iterdir()) == ["step_1.valid.all.json", "step_2.valid.all.json"]


def test_an_average_of_kept_steps_is_their_mean_with_the_last_ones_statistics_and_a_candidate(
    impact_data, tmp_path, tiny_config
):
    cfg = tiny_config("train.steps=3", "train.keep_every=1", "train.checkpoint_every=1")
    train(cfg, impact_data, "hcmt", tmp_path / "run", progress=False, device="cpu")
    out = average(tmp_path / "run", [3, 1])
    assert out.name == "avg_1_3.pt"
    one, three = (torch.load(tmp_path / "run" / f"step_{n}.pt", weights_only=True) for n in (1, 3))
    got = torch.load(out, weights_only=True)
    model = Run.load(tmp_path / "run", "cpu", "avg_1_3").model
    buffers = {name for name, _ in model.named_buffers()}
    assert buffers and any(k.endswith("sum") for k in buffers)  # the normalizers' statistics are buffers
    for k, v in got["model"].items():
        want = three["model"][k] if k in buffers else (one["model"][k] + three["model"][k]) / 2
        assert torch.allclose(v, want, rtol=0, atol=1e-7), k
    assert not all(torch.equal(one["model"][k], three["model"][k]) for k in got["model"] if k not in buffers)
    assert got["step"] == 3 and got["averaged_steps"] == [1, 3] and "optimizer" not in got
    assert Run.load(tmp_path / "run", "cpu", "avg_1_3").checkpoint_step == 3
    assert kept(RunFolder(tmp_path / "run"))[-1] == "avg_1_3"
    with pytest.raises(InputError, match="avg_1_2.pt: no such checkpoint"):
        Run.load(tmp_path / "run", "cpu", "avg_1_2")  # never silently the latest
    with pytest.raises(InputError, match="step_7.pt: no such checkpoint"):
        average(tmp_path / "run", [1, 7])
    with pytest.raises(InputError, match="at least two"):
        average(tmp_path / "run", [2, 2])
