"""Training, rollout and evaluation end to end on small data; resume equality; DDP; adapters; guards."""

import functools
import json
import os
import pickle
import signal
import socket
import subprocess
import sys
import time

import h5py
import numpy as np
import pytest
import torch
import yaml

import hcmt.training.build as build_module
import hcmt.training.trainer as trainer_module
from conftest import TINY
from hcmt.cli import main as cli
from hcmt.config import Config
from hcmt.data.format import NodeType, Split, open_split
from hcmt.domains.adapters import config_adapter, get_adapter, node_features
from hcmt.domains.frames import input_graph
from hcmt.domains.trajectory import build_graph, load_split
from hcmt.errors import DatasetError, RolloutError
from hcmt.graph.batch import PadSizes
from hcmt.inference.evaluate import evaluate
from hcmt.inference.metrics import Rmse
from hcmt.inference.quantities import CONTACT_TOL
from hcmt.inference.rollout import rollout
from hcmt.inference.rollout_files import run_rollouts
from hcmt.inference.run import Run, load_run
from hcmt.models import Normalizer, architecture
from hcmt.training import train
from hcmt.training.dataset import FrameDataset, StepSampler, pad_sizes
from hcmt.training.policy import TrainingPolicy
from hcmt.training.schedule import learning_rate
from hcmt.viz.curves import rollout_errors
from layouts import deforming_plate_tfrecord, ggns_pickles, sphere_simple_tfrecord, write_impact_like

pytestmark = pytest.mark.slow  # trains and rolls out real runs (DDP in a subprocess)

# this file's runs: conftest's TINY, then these (MGN/GT at 2 blocks, a log line every step, a checkpoint every 2,
# validation on one trajectory every 3, contact radius 0.3)
EXTRA = [
    "model.blocks=2",
    "train.log_every=1",
    "train.checkpoint_every=2",
    "train.valid_every=3",
    "train.valid_trajectories=1",
    "train.contact_radius=0.3",
]


@pytest.fixture(scope="module")
def impact(tmp_path_factory):
    return write_impact_like(tmp_path_factory.mktemp("impact") / "data")


@pytest.mark.parametrize("model", ["hcmt", "mgn", "gt"])
def test_tiny_end_to_end(impact, tmp_path, model, tiny_config):
    cfg = tiny_config(*EXTRA, "train.steps=4")
    summary = train(cfg, impact, model, tmp_path / "run", seed=1, progress=False)
    assert summary["steps"] == 4 and np.isfinite(summary["final_loss"])
    for f in ("run.yaml", "checkpoint.pt", "best.pt", "log.jsonl", "train_stats.json"):
        assert (tmp_path / "run" / f).is_file(), f
    assert any(p.name.startswith("events") for p in (tmp_path / "run" / "tb").iterdir())
    logs = [json.loads(l) for l in (tmp_path / "run" / "log.jsonl").read_text().splitlines()]
    assert [r["step"] for r in logs if "loss" in r] == [1, 2, 3, 4]
    assert any("valid/position_rmse_all" in r for r in logs)
    m = evaluate(Run.load(tmp_path / "run", "cpu"), impact, "test")
    assert isinstance(m.position, Rmse) and m.stress is not None
    assert np.isfinite(m.position.rmse_all) and m.inference_ms_per_step > 0
    assert json.loads((tmp_path / "run" / "metrics_test.json").read_text())["trajectories"] == 1
    evaluate(Run.load(tmp_path / "run", "cpu"), impact, "valid")  # another split never overwrites the test metrics
    assert json.loads((tmp_path / "run" / "metrics_test.json").read_text())["split"] == "test"
    assert json.loads((tmp_path / "run" / "metrics_valid.json").read_text())["split"] == "valid"


def test_rollout_imposes_boundary_conditions(impact, tmp_path, tiny_config):
    cfg = tiny_config(*EXTRA, "train.steps=2")
    train(cfg, impact, "mgn", tmp_path / "run", progress=False)
    model, info = load_run(tmp_path / "run")
    (traj,) = load_split(impact, "test", get_adapter("impact_plate"), 0)
    r = rollout(model, get_adapter("impact_plate"), traj, 0.3)
    nt = traj.static["node_type"]
    pred, true = r["world_pos"], traj.world_pos
    assert torch.equal(pred[:, nt == NodeType.HANDLE], true[:, nt == NodeType.HANDLE])
    assert torch.equal(pred[:, nt == NodeType.SYMMETRIC, 0], true[:, nt == NodeType.SYMMETRIC, 0])
    assert torch.equal(pred[:2], true[:2])  # history frames come from the data
    assert not torch.equal(pred[2:, nt == NodeType.NORMAL], true[2:, nt == NodeType.NORMAL])


def test_non_finite_guard_names_trajectory_and_step(impact, tmp_path, tiny_config):
    cfg = tiny_config(*EXTRA, "train.steps=2")
    train(cfg, impact, "mgn", tmp_path / "run", progress=False)
    model, _ = load_run(tmp_path / "run")
    with torch.no_grad():
        model.decoder[-1].bias.fill_(float("nan"))
    (traj,) = load_split(impact, "test", get_adapter("impact_plate"), 0)
    with pytest.raises(RolloutError, match=r"trajectory traj_00000: .*non-finite at step 2"):
        rollout(model, get_adapter("impact_plate"), traj, 0.3)


def test_resume_ends_with_the_same_parameters(impact, tmp_path, tiny_config):
    """Bit for bit on the CPU (CUDA: test_resume_on_cuda)."""
    cfg = tiny_config(*EXTRA, "train.steps=6", "train.noise_std=0.01", "train.keep_every=4")
    train(cfg, impact, "hcmt", tmp_path / "straight", seed=3, progress=False, device="cpu")
    train(cfg, impact, "hcmt", tmp_path / "resumed", seed=3, progress=False, stop_at=3, device="cpu")
    train(cfg, impact, "hcmt", tmp_path / "resumed", seed=3, progress=False, resume=True, device="cpu")
    a = torch.load(tmp_path / "straight" / "checkpoint.pt", weights_only=False)
    b = torch.load(tmp_path / "resumed" / "checkpoint.pt", weights_only=False)
    assert a["step"] == b["step"] == 6
    for k in a["model"]:
        assert torch.equal(a["model"][k], b["model"][k]), k
    # train.keep_every: step 4's checkpoint is kept beside the latest (step 6), the same in both runs
    for run in ("straight", "resumed"):
        assert sorted(p.name for p in (tmp_path / run).glob("step_*.pt")) == ["step_4.pt"], run
    kept = [torch.load(tmp_path / run / "step_4.pt", weights_only=False) for run in ("straight", "resumed")]
    assert kept[0]["step"] == kept[1]["step"] == 4
    assert all(torch.equal(kept[0]["model"][k], kept[1]["model"][k]) for k in a["model"])
    assert not all(torch.equal(kept[0]["model"][k], a["model"][k]) for k in a["model"])
    assert Run.load(tmp_path / "resumed", "cpu", "step_4").model is not None
    with pytest.raises(ValueError, match="already holds a run; pass resume=True"):
        train(cfg, impact, "hcmt", tmp_path / "straight", seed=3, progress=False)
    with pytest.raises(ValueError, match=r"config\.train\.noise_std: 0\.01 \(run\) vs"):
        train(
            tiny_config(*EXTRA, "train.steps=9"),
            impact,
            "hcmt",
            tmp_path / "straight",
            seed=3,
            progress=False,
            resume=True,
        )


def free_port() -> int:
    """A TCP port free right now (the OS picks it), so two suites on one machine do not collide."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def test_two_process_ddp(impact, tmp_path):
    cmd = [
        sys.executable,
        "-m",
        "torch.distributed.run",
        "--nproc_per_node=2",
        f"--master_port={free_port()}",
        "-m",
        "hcmt",
        "train",
        "--config",
        "impact_plate_cpu",
        "--data",
        str(impact),
        "--model",
        "hcmt",
        "--steps",
        "3",
        "--out",
        str(tmp_path / "ddp"),
        "--no-progress",
    ]
    cmd += sum((["--set", s] for s in TINY + EXTRA), [])
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-3000:]
    stats = json.loads((tmp_path / "ddp" / "train_stats.json").read_text())
    assert stats["world_size"] == 2 and stats["steps"] == 3


@pytest.mark.parametrize("kind", ["deforming_plate", "sphere_simple", "deformable_plate"])
def test_adapters_on_official_layouts(tmp_path, kind, tiny_config):
    src = tmp_path / "src"
    {
        "deforming_plate": deforming_plate_tfrecord,
        "sphere_simple": sphere_simple_tfrecord,
        "deformable_plate": ggns_pickles,
    }[kind](src)
    assert cli(["convert", str(src), str(tmp_path / "data")]) == 0
    radius = {"deforming_plate": 0.03, "sphere_simple": 0.05, "deformable_plate": 0.08}[kind]
    # the paper's excluded Deforming Plate trajectories 173 and 233 do not exist in a 2-trajectory file
    cfg = tiny_config(
        *EXTRA, "train.steps=2", f"train.contact_radius={radius}", "data.exclude_trajectories=[]", base=f"{kind}_cpu"
    )
    train(cfg, tmp_path / "data", "hcmt", tmp_path / "run", progress=False)
    m = evaluate(Run.load(tmp_path / "run", "cpu"), tmp_path / "data", "test")
    assert np.isfinite(m.position.rmse_all)
    assert (m.stress is not None) == get_adapter(kind).stress_output
    # prescribed obstacles and handles follow the data exactly
    with h5py.File(tmp_path / "run" / "rollout_test.h5") as f, open_split(tmp_path / "data", "test") as s:
        pred, truth = f["traj_00000/world_pos"][()], s[0]
    fixed = np.isin(truth["node_type"].reshape(-1), [NodeType.HANDLE] + list(get_adapter(kind).prescribed))
    np.testing.assert_array_equal(pred[:, fixed], truth["world_pos"][:, fixed])


def test_cli_train_rollout_evaluate_compare(impact, tmp_path, capsys):
    runs = []
    for model, seed in (("hcmt", 0), ("hcmt", 1), ("mgn", 0)):
        run = tmp_path / f"{model}{seed}"
        args = [
            "train",
            "--config",
            "impact_plate_cpu",
            "--data",
            str(impact),
            "--model",
            model,
            "--steps",
            "2",
            "--seed",
            str(seed),
            "--out",
            str(run),
            "--no-progress",
        ] + sum((["--set", s] for s in TINY + EXTRA), [])
        assert cli(args) == 0
        assert cli(["rollout", str(run), "--data", str(impact), "--split", "test"]) == 0
        assert (run / "rollout_test.h5").is_file()
        assert cli(["evaluate", str(run), "--data", str(impact), "--split", "test"]) == 0
        runs.append(str(run))
    capsys.readouterr()
    assert cli(["compare", *runs, "--json", str(tmp_path / "table.json")]) == 0
    out = capsys.readouterr().out
    assert "HCMT" in out and "MGN" in out and "±" in out
    table = json.loads((tmp_path / "table.json").read_text())
    hc = [json.loads((tmp_path / f"hcmt{s}" / "metrics_test.json").read_text())["position"]["rmse_all"] for s in (0, 1)]
    assert table["HCMT"]["position"]["rmse_all"]["n"] == 2
    assert table["HCMT"]["position"]["rmse_all"]["mean"] == pytest.approx(np.mean(hc))
    assert table["HCMT"]["position"]["rmse_all"]["std"] == pytest.approx(np.std(hc, ddof=1))
    assert cli(["compare", str(tmp_path)]) == 2  # not a run: clear error


def test_graph_batching_trains(impact, tmp_path, tiny_config):
    """batch_size > 1 collates several frames (from different trajectories) into one disconnected graph."""
    cfg = tiny_config(*EXTRA, "train.steps=2", "train.batch_size=2")
    s = train(cfg, impact, "hcmt", tmp_path / "run", progress=False)
    assert s["steps"] == 2 and np.isfinite(s["final_loss"])


def test_learning_rate_decays_from_lr_to_lr_final():
    assert learning_rate(0, 100, 1e-4, 1e-6) == pytest.approx(1e-4)
    assert learning_rate(50, 100, 1e-4, 1e-6) == pytest.approx(1e-5)
    assert learning_rate(100, 100, 1e-4, 1e-6) == pytest.approx(1e-6)


def test_evaluate_rolls_out_again_after_more_training(impact, tmp_path, tiny_config):
    cfg = tiny_config(*EXTRA, "train.steps=2")
    train(cfg, impact, "mgn", tmp_path / "run", progress=False)
    evaluate(Run.load(tmp_path / "run", "cpu", "checkpoint"), impact, "test")
    with h5py.File(tmp_path / "run" / "rollout_test.h5") as f:
        assert f.attrs["checkpoint_step"] == 2
    longer = tiny_config(*EXTRA, "train.steps=4")  # resume may extend the schedule
    train(longer, impact, "mgn", tmp_path / "run", progress=False, resume=True)
    evaluate(Run.load(tmp_path / "run", "cpu", "checkpoint"), impact, "test")
    with h5py.File(tmp_path / "run" / "rollout_test.h5") as f:
        assert f.attrs["checkpoint_step"] == 4


def test_dataset_without_the_adapters_fields_is_refused(tmp_path, tiny_config):
    src = tmp_path / "src"
    sphere_simple_tfrecord(src)
    assert cli(["convert", str(src), str(tmp_path / "data")]) == 0
    cfg = tiny_config(*EXTRA, "train.steps=1")  # Impact Plate needs density, modulus, stress
    with pytest.raises(DatasetError, match=r"impact_plate adapter .* needs fields \['density', 'modulus', 'stress'\]"):
        train(cfg, tmp_path / "data", "mgn", tmp_path / "run", progress=False)
    with pytest.raises(ValueError, match="out of range"):
        train(
            tiny_config(*EXTRA, "train.steps=1", "data.exclude_trajectories=[5]", base="sphere_simple_cpu"),
            tmp_path / "data",
            "mgn",
            tmp_path / "run2",
            progress=False,
        )


def test_error_curves_roll_out_the_trajectories_an_old_rollout_lacks(tmp_path, tiny_config):
    data = write_impact_like(tmp_path / "data", n_test=2)
    train(tiny_config(*EXTRA, "train.steps=1"), data, "mgn", tmp_path / "run", progress=False)
    run = Run.load(tmp_path / "run", "cpu")
    run_rollouts(run, data, "test", limit=1)
    errors = rollout_errors([run], data, "test")
    assert errors["MGN"]["trajectories"] == ["traj_00000", "traj_00001"]


def test_step_decay_is_the_authors_schedule():
    """train.lr_decay_steps: 1e-4 * 0.1^(step / 1e6), no floor (yuyudeep/hcmt run_model.py)."""
    assert learning_rate(0, 10, 1e-4, 1e-6, decay_steps=1_000_000) == pytest.approx(1e-4)
    assert learning_rate(1_000_000, 10, 1e-4, 1e-6, decay_steps=1_000_000) == pytest.approx(1e-5)
    assert learning_rate(3_000_000, 10, 1e-4, 1e-6, decay_steps=1_000_000) == pytest.approx(1e-7)  # below lr_final


def test_official_contact_pairs_join_obstacle_and_normal_nodes_only(impact):
    radius = 10.0  # every pair of the two bodies is in range
    graphs = {}
    for pairs in ("all", "official"):
        adapter = config_adapter(Config.from_dict({"dataset": "impact_plate", "train": {"contact_pairs": pairs}}))
        (traj,) = load_split(impact, "test", adapter, 0)
        x = traj.world_pos[2]
        graphs[pairs] = (
            build_graph(traj, x, node_features(adapter, traj.static, x, traj.world_pos[1], x), radius),
            traj.static["node_type"],
        )
    g, nt = graphs["official"]
    types = {tuple(sorted(p)) for p in nt[g.contact_edges].T.tolist()}
    assert types == {(int(NodeType.NORMAL), int(NodeType.OBSTACLE))}
    g_all, _ = graphs["all"]
    assert g_all.contact_edges.shape[1] > g.contact_edges.shape[1]


@pytest.mark.parametrize(
    "args,message",
    [
        (
            ["--set", "model.attention=softmax"],
            "model.attention: unknown value 'softmax'; expected one of paper, official",
        ),
        (
            ["--set", "train.contact_pairs=some"],
            "train.contact_pairs: unknown value 'some'; expected one of all, official",
        ),
        (["--steps", "0"], "argument --steps: expected a whole number from 1 to 1,000,000,000, got '0'"),
        (["--steps", "-5"], "argument --steps: expected a whole number from 1 to 1,000,000,000, got '-5'"),
        (["--set", "train.steps=0"], "--set 'train.steps=0': train.steps must be a whole number >= 1, got 0"),
    ],
)
def test_bad_settings_are_refused_before_any_work(impact, tmp_path, capsys, args, message):
    rc = cli(
        [
            "train",
            "--config",
            "impact_plate_cpu",
            "--data",
            str(impact),
            "--model",
            "hcmt",
            "--out",
            str(tmp_path / "run"),
            *args,
        ]
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and message in err[0]
    assert not (tmp_path / "run").exists()


def test_interrupted_training_saves_and_says_how_to_resume(impact, tmp_path):
    """SIGINT in the middle of training: one line naming the saved step and the resume command; resuming
    finishes the run."""
    run = tmp_path / "run"
    cmd = [
        sys.executable,
        "-m",
        "hcmt",
        "train",
        "--config",
        "impact_plate_cpu",
        "--data",
        str(impact),
        "--model",
        "mgn",
        "--out",
        str(run),
        "--no-progress",
        "--steps",
        "400",
    ]
    cmd += [a for t in TINY + EXTRA for a in ("--set", t)]
    proc = subprocess.Popen(
        cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env={**os.environ, "OMP_NUM_THREADS": "1"}
    )
    deadline = time.time() + 120
    log = run / "log.jsonl"
    while time.time() < deadline and not (log.is_file() and log.read_text().count("\n") >= 3):
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err
    assert "checkpoint of step" in lines[0] and "--resume" in lines[0]
    saved = torch.load(run / "checkpoint.pt", weights_only=True)["step"]
    assert 0 < saved < 400 and f"step {saved} of 400" in lines[0]
    assert (
        cli(
            [
                "train",
                "--config",
                "impact_plate_cpu",
                "--data",
                str(impact),
                "--model",
                "mgn",
                "--out",
                str(run),
                "--no-progress",
                "--steps",
                "400",
                "--resume",
            ]
            + [a for t in TINY + EXTRA for a in ("--set", t)]
        )
        == 0
    )
    assert torch.load(run / "checkpoint.pt", weights_only=True)["step"] == 400


def test_batched_rollout_equals_one_by_one(impact, tmp_path, tiny_config):
    cfg = tiny_config(*EXTRA, "train.steps=2")
    train(cfg, impact, "hcmt", tmp_path / "run", progress=False)
    assert cli(["rollout", str(tmp_path / "run"), "--data", str(impact), "--split", "train", "--batch", "2"]) == 0
    with h5py.File(tmp_path / "run" / "rollout_train.h5") as f:
        batched = {k: f[k]["world_pos"][()] for k in f}
    assert cli(["rollout", str(tmp_path / "run"), "--data", str(impact), "--split", "train"]) == 0
    with h5py.File(tmp_path / "run" / "rollout_train.h5") as f:
        assert len(f) == 2
        for k in f:
            np.testing.assert_allclose(batched[k], f[k]["world_pos"][()], rtol=0, atol=1e-5)


def test_compiled_rollouts_equal_plain(impact, tmp_path, monkeypatch, tiny_config):
    """--compile default rolls out through torch.compile with symbolic sizes on the graphs as they are, max-autotune
    (static shapes, like CUDA graphs) on padded graphs (eager backend here: Dynamo traces, nothing is built), aot
    through the exported forward built once from the first graph (stood in here; the package itself:
    tests/models/test_export.py); the trajectories equal the plain rollout's, and ``auto`` stays eager for a rollout
    this short."""
    cfg = tiny_config(*EXTRA, "train.steps=2")
    train(cfg, impact, "gt", tmp_path / "run", progress=False, device="cpu")
    compile_, calls = torch.compile, []
    monkeypatch.setattr(
        torch,
        "compile",
        lambda model, **kw: calls.append(kw) or compile_(model, backend="eager", dynamic=kw["dynamic"]),
    )
    import hcmt.inference.rollout as rollout_module
    from hcmt.models.export import with_dummies

    exports = []  # aot: the package's forward stood in by the model on the same dummy-extended graph (no compiler)
    monkeypatch.setattr(
        rollout_module,
        "exported_forward",
        lambda model, example: (
            exports.append(example) or (lambda g: model(with_dummies(g), accumulate=False)[: g.num_nodes])
        ),
    )
    out = {}
    for mode in ("none", "default", "max-autotune", "auto", "aot"):
        assert (
            cli(
                [
                    "rollout",
                    str(tmp_path / "run"),
                    "--data",
                    str(impact),
                    "--split",
                    "train",
                    "--batch",
                    "2",
                    "--device",
                    "cpu",
                    "--compile",
                    mode,
                ]
            )
            == 0
        )
        with h5py.File(tmp_path / "run" / "rollout_train.h5") as f:
            out[mode] = {k: f[k]["world_pos"][()] for k in f}
    assert [c["dynamic"] for c in calls] == [True, False]  # default: symbolic sizes; max-autotune: padded
    assert len(exports) == 1  # aot: built once, from the first step's graph
    assert out["none"].keys() == out["default"].keys() and len(out["none"]) == 2
    for mode in ("default", "max-autotune", "auto", "aot"):
        for k in out["none"]:
            np.testing.assert_allclose(out[mode][k], out["none"][k], rtol=0, atol=1e-5)


def test_unknown_or_unavailable_device_is_one_line(impact, tmp_path, capsys, tiny_config):
    cfg = tiny_config(*EXTRA, "train.steps=1")
    train(cfg, impact, "mgn", tmp_path / "run", progress=False)
    run, data, out = str(tmp_path / "run"), str(impact), str(tmp_path / "out")
    for device in ("tpu", "cuda:7" if torch.cuda.is_available() else "cuda"):
        for cmd in (
            ["evaluate", run, "--data", data],
            ["plot", run, "--data", data, "--out", out, "--only", "errors"],
            ["export", run, "--data", data, "--out", out],
        ):
            assert cli(cmd + ["--device", device]) == 2, cmd
            err = capsys.readouterr().err.strip().splitlines()
            assert len(err) == 1 and f"--device {device}" in err[0].replace("'", ""), (cmd, err)
    assert not (tmp_path / "run" / "rollout_test.h5").exists()  # refused before any rollout
    assert cli(["export", run, "--data", data, "--out", out, "--device", "cpu"]) == 0
    assert (tmp_path / "run" / "rollout_test.h5").is_file() and list((tmp_path / "out").rglob("*.pvd"))


def test_run_folder_rules(impact, tmp_path, capsys):
    """Resume alone with the saved settings, fewer steps refused, no duplicate log steps, a lock against a second
    writer, nothing left behind by a run that fails before its first checkpoint."""
    run = tmp_path / "run"
    base = [
        "train",
        "--config",
        "impact_plate_cpu",
        "--data",
        str(impact),
        "--model",
        "mgn",
        "--out",
        str(run),
        "--no-progress",
    ] + [a for t in TINY + EXTRA for a in ("--set", t)]
    assert cli(base + ["--steps", "3"]) == 0
    assert cli(["train", "--resume", "--out", str(run), "--steps", "5", "--no-progress"]) == 0
    assert torch.load(run / "checkpoint.pt", weights_only=True)["step"] == 5
    steps = [json.loads(l)["step"] for l in (run / "log.jsonl").read_text().splitlines() if "loss" in json.loads(l)]
    assert steps == [1, 2, 3, 4, 5]
    capsys.readouterr()
    assert cli(["train", "--resume", "--out", str(run), "--steps", "2", "--no-progress"]) == 2
    assert "has done 5 steps" in capsys.readouterr().err
    assert cli(base + ["--steps", "6", "--resume", "--set", "train.lr=0.5"]) == 2
    assert "config.train.lr: 0.001 (run) vs 0.5 (now)" in capsys.readouterr().err
    (run / ".lock").write_text(str(os.getpid()))  # a live process holds the run
    assert cli(["train", "--resume", "--out", str(run), "--steps", "6", "--no-progress"]) == 2
    assert "being written by another training process" in capsys.readouterr().err
    (run / ".lock").unlink()
    bad = tmp_path / "bad"
    assert (
        cli(
            [
                "train",
                "--config",
                "impact_plate_cpu",
                "--data",
                str(tmp_path / "nowhere"),
                "--model",
                "mgn",
                "--out",
                str(bad),
                "--no-progress",
            ]
        )
        == 2
    )
    assert not bad.exists()


def test_bf16_and_checkpointed_blocks_train(impact, tmp_path, tiny_config):
    cfg = tiny_config(*EXTRA, "train.steps=2", "train.precision=bf16", "train.checkpoint_blocks=true")
    s = train(cfg, impact, "hcmt", tmp_path / "run", progress=False)
    assert s["steps"] == 2 and np.isfinite(s["final_loss"])


def test_dataloader_workers_change_no_result(impact, tmp_path, tiny_config):
    """train.workers builds graphs in DataLoader processes; the parameters end bit for bit as with 0 workers
    (noise and data order are functions of the step, not of the process)."""
    params = []
    for workers in (0, 2):
        cfg = tiny_config(
            *EXTRA, "train.steps=4", "train.noise_std=0.01", "train.batch_size=2", f"train.workers={workers}"
        )
        train(cfg, impact, "hcmt", tmp_path / f"w{workers}", seed=2, progress=False)
        params.append(torch.load(tmp_path / f"w{workers}" / "checkpoint.pt", weights_only=True)["model"])
    assert all(torch.equal(params[0][k], params[1][k]) for k in params[0])


def test_frame_dataset_pickles_without_its_trajectories(impact):
    ds = FrameDataset(impact, "train", get_adapter("impact_plate"), 1, True, 0.3, noise_std=0.01, seed=1)
    graph, target, mask = ds[0]
    clone = pickle.loads(pickle.dumps(ds))
    assert clone.source._split is None and not clone.source._static  # reopened lazily in the worker
    g2, t2, m2 = clone[0]
    assert torch.equal(target, t2) and torch.equal(graph.node_features, g2.node_features) and len(ds) == len(clone)
    eager = FrameDataset(
        impact, "train", get_adapter("impact_plate"), 1, True, 0.3, noise_std=0.01, seed=1, in_memory=True
    )
    assert pickle.loads(pickle.dumps(eager)).source._trajs is None


def test_contact_free_weight_scales_the_loss_of_frames_where_nothing_touches(impact):
    """train.contact_free_weight w: an item whose input frame has no contact pair within CONTACT_TOL (the read-outs'
    touch tolerance) gets its loss mask times w, an item where something touches keeps it; the loss divides by the
    mask's entries, not its weights, so such a frame's loss is w times. Contact radii of 1e-9 (no pairs) and 1e3
    (every pair, the touching ones among them) give frames of both kinds."""
    adapter, policy, free = get_adapter("impact_plate"), TrainingPolicy(), []
    for radius in (1e-9, 1e3):
        plain, heavy = (
            FrameDataset(impact, "train", adapter, 1, True, radius, noise_std=0.01, seed=1, contact_free_weight=w)
            for w in (1.0, 3.0)
        )
        for i in range(len(plain)):
            (graph, target, mask), (_, target3, mask3) = plain[i], heavy[i]
            free.append(not bool((graph.contact_features[:, -1] <= CONTACT_TOL).any()))
            assert torch.equal(target, target3) and torch.equal(mask3, mask * 3.0 if free[-1] else mask)
            assert policy.loss_count(graph, mask3) == policy.loss_count(graph, mask) == mask.sum()
    assert any(free) and not all(free)


def test_lazily_read_run_ends_with_the_eager_in_memory_runs_parameters(impact, tmp_path, monkeypatch, tiny_config):
    """The training path reads the frames of each item from the file (FrameDataset's SplitReader); the run ends
    bit for bit as one that holds the split in memory (load_split), pushforward items included."""
    cfg = tiny_config(*EXTRA, "train.steps=5", "train.noise_std=0.01", "train.batch_size=2", "train.pushforward=0.5")
    train(cfg, impact, "hcmt", tmp_path / "lazy", seed=4, progress=False, device="cpu")
    monkeypatch.setattr(build_module, "FrameDataset", functools.partial(FrameDataset, in_memory=True))
    train(cfg, impact, "hcmt", tmp_path / "eager", seed=4, progress=False, device="cpu")
    a, b = (torch.load(tmp_path / name / "checkpoint.pt", weights_only=True)["model"] for name in ("lazy", "eager"))
    assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


def _held_arrays(obj, seen=None) -> list:
    """Every numpy array and tensor reachable from ``obj`` through attributes, dicts, lists and tuples."""
    seen = set() if seen is None else seen
    if id(obj) in seen or isinstance(obj, (str, bytes, int, float, type, type(None))):
        return []
    seen.add(id(obj))
    if isinstance(obj, (np.ndarray, torch.Tensor)):
        return [obj]
    if isinstance(obj, dict):
        items = list(obj.keys()) + list(obj.values())
    elif isinstance(obj, (list, tuple, set)):
        items = list(obj)
    else:
        items = list(getattr(obj, "__dict__", {}).values())
    return [a for item in items for a in _held_arrays(item, seen)]


def test_frame_dataset_holds_no_per_trajectory_arrays_after_building_items(tmp_path):
    """After building items of every trajectory, the dataset holds the index and the static fields and hierarchy
    of at most ``keep`` trajectories (an LRU), and no frames."""
    data = write_impact_like(tmp_path / "data", n_train=6, steps=6)
    ds = FrameDataset(data, "train", get_adapter("impact_plate"), 1, True, 0.3, noise_std=0.01, seed=1, keep=2)
    assert not _held_arrays(ds.source._static) and ds.source._split is None  # the index only: no array read yet
    for i in range(len(ds)):
        ds[i]
    held = _held_arrays(ds)
    assert len(ds.source._static) == 2 and len({int(t) for t in ds.frames[:, 0]}) == 6
    assert not [a for a in held if a.ndim == 3 and a.shape[0] > 0]  # no [T, N, d] field, not even one frame
    statics = {id(a) for a in _held_arrays(ds.source._static)}  # the LRU's trajectories: static fields, hierarchy
    index = {id(a) for a in (ds.frames, ds.source.steps, ds.source.nodes, ds.source.index)}
    assert {id(a) for a in held} - statics == index


def test_a_rank_reads_only_the_frames_of_its_own_keys(tmp_path, monkeypatch):
    """Each DDP rank's StepSampler keys name the frames it builds: the rank reads those frames (x^{t-1}..x^{t+1})
    and the static fields of their trajectories, nothing else, and never a whole trajectory."""
    data = write_impact_like(tmp_path / "data", n_train=6, steps=6)
    reads = []
    read = Split.read
    monkeypatch.setattr(
        Split,
        "read",
        lambda self, i, fields, frames=None, num_nodes=None: (
            reads.append((self.names[i], frames)) or read(self, i, fields, frames, num_nodes)
        ),
    )
    monkeypatch.setattr(Split, "__getitem__", lambda self, i: pytest.fail("a whole trajectory was read"))
    for rank in (0, 1):
        ds = FrameDataset(data, "train", get_adapter("impact_plate"), 1, True, 0.3, keep=1)
        reads.clear()
        keys = [k for step in StepSampler(ds, 2, seed=5, start=0, end=3, world=2, rank=rank) for k in step]
        for key in keys:
            ds[key]
        mine = [(ds.source.names[int(ds.frames[k[0]][0])], int(ds.frames[k[0]][1])) for k in keys]
        frames = {(name, t) for name, t in mine}
        got = {(name, t) for name, sl in reads if sl is not None for t in range(sl.start, sl.stop)}
        assert got == {(name, t + dt) for name, t in frames for dt in (-1, 0, 1)}
        assert {name for name, sl in reads if sl is None} <= {name for name, _ in mine}


@pytest.mark.parametrize("mode,padded", [("reduce-overhead", True), ("default", False)])
def test_compiled_training_matches_eager(impact, tmp_path, monkeypatch, tiny_config, mode, padded):
    """train.compile trains through torch.compile, pushforward predictions included, and the parameters end as the
    eager run's: on padded graphs of static shapes (``reduce-overhead``: CUDA graphs need them), or on the CPU in
    mode ``default`` with symbolic sizes on the graphs as they are (no padding). torch.compile runs with the eager
    backend here (Dynamo traces the model, no C++/Triton build: seconds, not minutes), which checks the padding, the
    eager normalizer accumulation and the tracing."""
    compile_ = torch.compile
    calls = []
    monkeypatch.setattr(
        torch,
        "compile",
        lambda model, **kw: calls.append(kw) or compile_(model, backend="eager", dynamic=kw["dynamic"]),
    )
    made, predictions = build_module.padded_forward, []
    monkeypatch.setattr(
        build_module,
        "padded_forward",
        lambda net, sizes: (
            lambda graph, forward=made(net, sizes): predictions.append(graph.num_nodes) or forward(graph)
        ),
    )
    params = {}
    for m in ("none", mode):
        cfg = tiny_config(
            *EXTRA,
            "train.steps=6",
            "train.noise_std=0.01",
            "train.batch_size=2",
            "train.pushforward=0.5",
            "train.pushforward_start=0",
            f"train.compile={m}",
        )
        train(cfg, impact, "hcmt", tmp_path / m, seed=2, progress=False, device="cpu")
        params[m] = torch.load(tmp_path / m / "checkpoint.pt", weights_only=True)["model"]
    assert [(kw["mode"], kw["dynamic"]) for kw in calls] == [(None if mode == "default" else mode, not padded)]
    assert params["none"].keys() == params[mode].keys()
    moved = 0
    for k, v in params["none"].items():
        torch.testing.assert_close(params[mode][k], v, rtol=1e-5, atol=1e-6, msg=k)
        moved += k.endswith("count") and v.item() > 0
    assert moved  # the normalizers did accumulate (the comparison covers their statistics)
    # pushforward predictions went through the padded compiled model, or (symbolic sizes) through no padding
    assert bool(predictions) == padded


def test_compile_refuses_lpe_and_deterministic_is_scoped(impact, tmp_path, tiny_config):
    cfg = tiny_config(*EXTRA, "train.steps=1", "train.compile=default")
    with pytest.raises(ValueError, match="lpe ablation"):
        train(cfg, impact, "hcmt", tmp_path / "lpe", ablation="lpe", progress=False, device="cpu")
    seen = []
    step = trainer_module.Trainer.step

    def tr_step(self, *a):
        return seen.append(torch.are_deterministic_algorithms_enabled()) or step(self, *a)

    cfg = tiny_config(*EXTRA, "train.steps=2", "train.deterministic=true")
    try:
        trainer_module.Trainer.step = tr_step
        train(cfg, impact, "hcmt", tmp_path / "det", progress=False, device="cpu")
    finally:
        trainer_module.Trainer.step = step
    assert seen == [True, True] and not torch.are_deterministic_algorithms_enabled()


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA GPU")
@pytest.mark.parametrize("deterministic", [True, False])
def test_resume_on_cuda(impact, tmp_path, deterministic, tiny_config):
    """On CUDA, scatter sums are not reproducible by default: a resumed run matches within a tolerance;
    with train.deterministic it matches bit for bit."""
    cfg = tiny_config(
        *EXTRA, "train.steps=6", "train.noise_std=0.01", f"train.deterministic={str(deterministic).lower()}"
    )
    train(cfg, impact, "hcmt", tmp_path / "straight", seed=3, progress=False, device="cuda")
    train(cfg, impact, "hcmt", tmp_path / "resumed", seed=3, progress=False, device="cuda", stop_at=3)
    train(cfg, impact, "hcmt", tmp_path / "resumed", seed=3, progress=False, device="cuda", resume=True)
    a = torch.load(tmp_path / "straight" / "checkpoint.pt", weights_only=True)["model"]
    b = torch.load(tmp_path / "resumed" / "checkpoint.pt", weights_only=True)["model"]
    for k in a:
        if deterministic:
            assert torch.equal(a[k], b[k]), k
        else:
            torch.testing.assert_close(b[k], a[k], rtol=1e-4, atol=1e-5, msg=k)


def test_pad_sizes_from_the_hierarchies_equal_those_of_the_frames_graphs(impact):
    """train.compile sizes its padding from each trajectory's hierarchy, without building a graph per trajectory:
    the same sizes as the built graphs give."""
    ds = FrameDataset(impact, "train", get_adapter("impact_plate"), 1, True, 0.3)
    trajs = [ds.trajectory(ti) for ti in range(len(ds.source))]
    graphs = [input_graph(tr, tr.world_pos[1], tr.world_pos[0], tr.world_pos[2], 0.3) for tr in trajs]
    assert graphs[0].num_levels == 1
    for batch in (1, 3):
        assert pad_sizes(ds, batch) == PadSizes.of(graphs, batch)


# -- fine-tuning: train --init ---------------------------------------------------------------------------------------
def _normalizer_buffers(model) -> dict:
    return {
        f"{n}.{b}": t.clone()
        for n, m in model.named_modules()
        if isinstance(m, Normalizer)
        for b, t in m.named_buffers()
    }


def test_init_starts_from_the_source_weights_and_keeps_or_reaccumulates_normalizers(impact, tmp_path, tiny_config):
    """``init``: step 0 of the new run holds the source's parameters exactly (a 0-step run is refused, so one step
    with lr 1e-30, below float32 resolution, shows it); ``keep`` leaves the source's normalizer statistics untouched
    through training; ``reaccumulate`` zeroes them and counts afresh; run.yaml records the source."""
    src = tmp_path / "src"
    train(tiny_config(*EXTRA, "train.steps=4"), impact, "hcmt", src, seed=1, progress=False)
    source = Run.load(src, "cpu").model
    frozen = tmp_path / "frozen"
    train(
        tiny_config(*EXTRA, "train.steps=3", "train.lr=1e-30", "train.lr_final=1e-30", "train.pushforward=0"),
        impact,
        "hcmt",
        frozen,
        seed=2,
        progress=False,
        init=str(src),
    )
    tuned = load_run(frozen, "checkpoint")[0]
    for (k, a), b in zip(source.state_dict().items(), tuned.state_dict().values()):
        torch.testing.assert_close(a, b, rtol=0, atol=0, msg=k)  # no step and frozen statistics: nothing moved
    assert load_run(frozen, "checkpoint")[1].init == {"from": str(src), "normalizers": "keep", "step": 3}
    fresh = tmp_path / "fresh"
    train(
        tiny_config(*EXTRA, "train.steps=3"),
        impact,
        "hcmt",
        fresh,
        seed=2,
        progress=False,
        init=str(src),
        init_normalizers="reaccumulate",
    )
    counts_src = {k: float(v) for k, v in _normalizer_buffers(source).items() if k.endswith("num_accumulations")}
    counts_new = {
        k: float(v)
        for k, v in _normalizer_buffers(load_run(fresh, "checkpoint")[0]).items()
        if k.endswith("num_accumulations")
    }
    assert all(counts_new[k] < counts_src[k] for k in counts_src if counts_src[k] > 3)  # started again from zero


def test_init_with_another_architecture_is_one_line_listing_the_differences(impact, tmp_path, tiny_config, capsys):
    train(tiny_config(*EXTRA, "train.steps=2"), impact, "hcmt", tmp_path / "src", seed=1, progress=False)
    rc = cli(
        [
            "train",
            "--config",
            "impact_plate_cpu",
            "--data",
            str(impact),
            "--model",
            "hcmt",
            "--out",
            str(tmp_path / "b"),
            "--steps",
            "2",
            "--init",
            str(tmp_path / "src"),
            "--no-progress",
            *(a for kv in TINY + EXTRA + ["model.hidden=24"] for a in ("--set", kv)),
        ]
    )
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1
    assert "its model differs from this run's: hidden 16 there, 24 here" in err
    assert not (tmp_path / "b").exists()
    rc = cli(["train", "--out", str(tmp_path / "src"), "--resume", "--init", "pretrained:impact_plate_small"])
    assert rc == 2 and "give one of them" in capsys.readouterr().err
    rc = cli(["train", "--out", str(tmp_path / "src"), "--resume", "--init", str(tmp_path / "src")])
    assert rc == 2 and "the same folder as --init" in capsys.readouterr().err  # refused before it reads anything


def test_ablation_flag_is_the_model_ablation_key_and_resume_keeps_it(impact, tmp_path, capsys):
    out = tmp_path / "abl"
    sets = [a for kv in TINY + EXTRA for a in ("--set", kv)]
    assert (
        cli(
            [
                "train",
                "--config",
                "impact_plate_cpu",
                "--data",
                str(impact),
                "--model",
                "hcmt",
                "--out",
                str(out),
                "--steps",
                "1",
                "--ablation",
                "only-hmt",
                "--no-progress",
                *sets,
            ]
        )
        == 0
    )
    info = Run.load(out, "cpu").info
    assert info.config.model.ablation == info.model["ablation"] == "only-hmt"
    assert cli(["train", "--out", str(out), "--resume", "--steps", "2", "--no-progress"]) == 0
    assert Run.load(out, "cpu").info.model["ablation"] == "only-hmt"
    capsys.readouterr()


def test_ablation_no_remesh_is_an_alias_of_data_remesh_false(impact, tmp_path, capsys):
    """``--ablation no-remesh`` (the paper's HCMT without remeshing) trains with ``data.remesh: false``: run.yaml
    holds the graph setting, the run builds the 2-hop hierarchy, and resuming keeps it."""
    out = tmp_path / "nr"
    sets = [a for kv in TINY + EXTRA for a in ("--set", kv)]
    assert (
        cli(
            [
                "train",
                "--config",
                "impact_plate_cpu",
                "--data",
                str(impact),
                "--model",
                "hcmt",
                "--out",
                str(out),
                "--steps",
                "1",
                "--ablation",
                "no-remesh",
                "--no-progress",
                *sets,
            ]
        )
        == 0
    )
    saved = yaml.safe_load((out / "run.yaml").read_text())
    assert saved["config"]["data"]["remesh"] is False and saved["config"]["model"]["ablation"] is None
    assert saved["model"]["ablation"] is None
    run = Run.load(out, "cpu")
    assert run.hierarchy_spec[1] is False and run.hierarchy_spec[0] > 0 and run.label == "HCMT (no-remesh)"
    assert cli(["train", "--out", str(out), "--resume", "--steps", "2", "--no-progress"]) == 0
    assert Run.load(out, "cpu").config.data.remesh is False
    capsys.readouterr()


def test_init_inherits_the_sources_model_settings_and_mgn_saves_only_its_own(impact, tmp_path, tiny_config, capsys):
    """``--init`` takes the source's ``model:`` section (its architecture and input features) and, without
    ``--config`` / ``--model``, its config and model: fine-tuning the shipped model needs no ``--set``."""
    shipped = Run.load("pretrained:impact_plate_small", "cpu")
    ft = tmp_path / "ft"
    assert (
        cli(
            [
                "train",
                "--init",
                "pretrained:impact_plate_small",
                "--data",
                str(impact),
                "--out",
                str(ft),
                "--steps",
                "1",
                "--no-progress",
                "--set",
                "train.valid_every=0",
            ]
        )
        == 0
    )
    info = Run.load(ft, "cpu").info
    assert architecture(info.model) == architecture(shipped.info.model)
    assert info.config.model == shipped.config.model and info.config.model.deformation
    src = tmp_path / "src"
    train(
        tiny_config(*EXTRA, "train.steps=1", "model.deformation=true", "model.attention=official"),
        impact,
        "hcmt",
        src,
        seed=1,
        progress=False,
    )
    assert (
        cli(
            [
                "train",
                "--config",
                "impact_plate_cpu",
                "--data",
                str(impact),
                "--out",
                str(tmp_path / "b"),
                "--steps",
                "1",
                "--init",
                str(src),
                "--no-progress",
                *(a for kv in EXTRA for a in ("--set", kv)),
            ]
        )
        == 0
    )
    model = Run.load(tmp_path / "b", "cpu").info.config.model
    assert (model.deformation, model.attention, model.hidden) == (True, "official", 16)  # none of them given
    mgn = tmp_path / "mgn"
    train(tiny_config(*EXTRA, "train.steps=1"), impact, "mgn", mgn, seed=1, progress=False)
    assert set(Run.load(mgn, "cpu").info.model) == {
        "name",
        "node_in",
        "mesh_in",
        "contact_in",
        "out",
        "hidden",
        "blocks",
    }
    assert (
        cli(
            [
                "train",
                "--data",
                str(impact),
                "--out",
                str(tmp_path / "mgn2"),
                "--steps",
                "1",
                "--init",
                str(mgn),
                "--no-progress",
            ]
        )
        == 0
    )
    with pytest.raises(ValueError, match="model.ablation only-hmt: an ablation of HCMT; model mgn has none"):
        train(tiny_config(*EXTRA, "train.steps=1", "model.ablation=only-hmt"), impact, "mgn", tmp_path / "x")
    capsys.readouterr()
