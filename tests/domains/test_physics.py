"""Impact physics: the training formulation options (target, noise nodes, γ, pushforward), the physics
metrics an engineer reads, design sweeps and --threads."""

import json
import shutil

import numpy as np
import pytest
import torch

from conftest import IMPACT_DATA
from hcmt.cli import auto_threads, main as cli, set_threads
from hcmt.config import Config, load_config
from hcmt.data.format import NodeType
from hcmt.design import sweep as sw
from hcmt.domains.adapters import config_adapter, get_adapter, integrate, noise_gamma, noise_mask, position_mask, target
from hcmt.domains.frames import input_graph
from hcmt.graph.build import frame_graph
from hcmt.inference.evaluate import evaluate
from hcmt.inference.physics import impact_metrics, summarize_impact
from hcmt.inference.run import Run
from hcmt.training import train
from hcmt.training.dataset import FrameDataset, collate_samples
from hcmt.training.schedule import keras_epsilon
from hcmt.training.trainer import Trainer
from summaries import fake_metrics

pytestmark = pytest.mark.slow  # training runs on generated data

FRAMES = IMPACT_DATA["frames"]
EXTRA = ["train.steps=4", "train.checkpoint_every=2"]  # this file's runs: conftest's TINY, then these


@pytest.fixture(scope="module")
def data(tmp_path_factory, impact_data):
    root = tmp_path_factory.mktemp("physics")
    shutil.copytree(impact_data, root / "data")  # the test run's dataset (conftest), a copy this module may change
    return root / "data"


# -- formulation options -----------------------------------------------------------------------------------------
@pytest.mark.parametrize("kind,order", [("velocity", 1), ("acceleration", 2)])
def test_target_option_sets_the_updater_and_the_updater_inverts_the_target(kind, order):
    adapter = config_adapter(Config.from_dict({"dataset": "impact_plate", "model": {"target": kind}}))
    assert adapter.order == order
    g = torch.Generator().manual_seed(0)
    prev, pos, nxt = (torch.randn(20, 2, generator=g) for _ in range(3))
    node_type = torch.full((20,), int(NodeType.NORMAL))
    tgt = target(adapter, pos, prev, nxt, torch.zeros(20))
    expected = nxt - pos if order == 1 else nxt - 2 * pos + prev
    torch.testing.assert_close(tgt[:, :2], expected)
    back, _ = integrate(adapter, tgt, pos, prev, nxt + 1.0, node_type)  # true_next read only at boundary nodes
    torch.testing.assert_close(back, nxt)


def test_gamma_defaults_per_target_and_an_explicit_value_wins():
    vel = Config.from_dict({"dataset": "impact_plate", "model": {}, "train": {}})
    acc = Config.from_dict({"dataset": "impact_plate", "model": {"target": "acceleration"}, "train": {}})
    assert noise_gamma(vel, config_adapter(vel)) == 1.0
    assert noise_gamma(acc, config_adapter(acc)) == 0.1
    acc = acc.with_overrides(["train.noise_gamma=0.5"])
    assert noise_gamma(acc, config_adapter(acc)) == 0.5
    assert load_config("impact_plate").train.noise_gamma is None  # per target unless set


def test_noise_nodes_predicted_reaches_the_ball_but_not_boundary_channels():
    adapter = get_adapter("impact_plate")
    nt = torch.tensor([NodeType.NORMAL, NodeType.OBSTACLE, NodeType.HANDLE, NodeType.SYMMETRIC])
    normal = noise_mask(adapter, nt, 2, "normal")
    predicted = noise_mask(adapter, nt, 2, "predicted")
    torch.testing.assert_close(normal, torch.tensor([[1.0, 1.0], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0]]))
    torch.testing.assert_close(predicted, position_mask(adapter, nt, 2))
    torch.testing.assert_close(predicted, torch.tensor([[1.0, 1.0], [1.0, 1.0], [0.0, 0.0], [0.0, 1.0]]))
    with pytest.raises(ValueError, match="noise_nodes.*normal, predicted"):
        noise_mask(adapter, nt, 2, "all")


def test_noise_on_predicted_nodes_moves_the_ball_in_training_samples(data):
    adapter = get_adapter("impact_plate")
    a = FrameDataset(data, "train", adapter, 0, True, 0.4, noise_std=1e-3, seed=1, noise_nodes="normal")
    b = FrameDataset(data, "train", adapter, 0, True, 0.4, noise_std=1e-3, seed=1, noise_nodes="predicted")
    tr = a.trajectory(0)
    ball = tr.static["node_type"].reshape(-1) == NodeType.OBSTACLE
    ga, ta, _ = a[0]
    gb, tb, _ = b[0]
    # the velocity target x^{t+1} - x~^t (γ 1) carries the noise: zero on the ball with NORMAL-only noise
    t = int(a.frames[0][1])
    clean = tr.world_pos[t + 1] - tr.world_pos[t]
    assert torch.equal(ta[ball, :2], clean[ball])
    assert (tb[ball, :2] - clean[ball]).abs().max() > 1e-4


def test_pushforward_input_is_the_models_prediction_and_the_target_lands_on_the_data(data, tmp_path, tiny_config):
    cfg = tiny_config(*EXTRA)
    train(cfg, data, "mgn", tmp_path / "run", progress=False)
    run = Run.load(tmp_path / "run", "cpu")
    adapter = run.adapter
    ds = FrameDataset(data, "train", adapter, 0, True, run.radius, noise_std=0.0, seed=3)
    i = next(k for k in range(len(ds)) if ds.frames[k][1] >= 2)
    ti, t = (int(v) for v in ds.frames[i])
    tr = ds.trajectory(ti)
    key = (i, 0, 0, ())
    plain = ds.pushforward_item(key, run.model, 0.0)
    torch.testing.assert_close(plain[1], ds[key][1])  # probability 0: the ordinary sample
    graph, tgt, mask = ds.pushforward_item(key, run.model, 1.0)
    w = tr.world_pos
    with torch.no_grad():  # the model's own step from frame t-1
        out = run.model.denormalize(run.model(input_graph(tr, w[t - 1], w[t - 2], w[t], run.radius), accumulate=False))
    pred, _ = integrate(adapter, out, w[t - 1], w[t - 2], w[t], tr.static["node_type"])
    assert (pred - w[t]).abs().max() > 1e-6  # the model is not exact: the test is not vacuous
    # input velocity feature x^t - x^{t-1} is the predicted one; the target takes x^t_pred to the data's x^{t+1}
    torch.testing.assert_close(pred + tgt[:, :2], w[t + 1], rtol=0, atol=1e-6)


def test_pushforward_training_resumes_exactly(data, tmp_path, tiny_config):
    cfg = tiny_config(
        *EXTRA,
        "train.pushforward=0.5",
        "model.target=acceleration",
        "train.noise_nodes=predicted",
        "train.noise_std=1e-3",
    )
    train(cfg, data, "mgn", tmp_path / "once", progress=False)
    train(cfg, data, "mgn", tmp_path / "twice", progress=False, stop_at=2)
    train(cfg, data, "mgn", tmp_path / "twice", progress=False, resume=True)
    a = torch.load(tmp_path / "once" / "checkpoint.pt", weights_only=True)["model"]
    b = torch.load(tmp_path / "twice" / "checkpoint.pt", weights_only=True)["model"]
    for k in a:
        assert torch.equal(a[k], b[k]), k


@pytest.mark.parametrize(
    "key,value,allowed",
    [("model.target", "accel", "velocity, acceleration"), ("train.noise_nodes", "ball", "normal, predicted")],
)
def test_unknown_formulation_values_are_refused_before_data_is_read(tmp_path, capsys, key, value, allowed):
    rc = cli(
        [
            "train",
            "--config",
            "impact_plate_cpu",
            "--data",
            str(tmp_path / "nothing"),
            "--model",
            "hcmt",
            "--out",
            str(tmp_path / "run"),
            "--set",
            f"{key}={value}",
        ]
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and key in err[0] and repr(value) in err[0] and allowed in err[0]
    assert not (tmp_path / "run").exists()


def test_pushforward_probability_outside_0_1_is_refused():
    with pytest.raises(ValueError, match="train.pushforward.*probability"):
        load_config("impact_plate_cpu", ["train.pushforward=1.5"])


# -- physics metrics ---------------------------------------------------------------------------------------------
def _impact(T=20, rebound=True, peak_frame=10, peak=100.0, defl=0.05):
    """A synthetic impact: plate nodes at r = 0..4 (r <= 2 contact, > 2 far), two ball nodes."""
    r = np.array([0.0, 1.0, 2.0, 3.0, 4.0])
    rest = np.concatenate([np.stack([r, np.zeros(5)], 1), [[0.0, 1.0], [0.5, 1.0]]])
    t = np.arange(T)[:, None]
    pos = np.repeat(rest[None], T, 0).astype(np.float64)
    shape = np.exp(-(((t - peak_frame) / 4.0) ** 2)) * (t > 0)  # frame 0 at rest
    pos[:, :5, 1] = -defl * shape * (1 - r / 5)[None]
    vy = -0.01 * np.ones(T)
    if rebound:
        vy[peak_frame:] = 0.01
    pos[:, 5:, 1] += np.cumsum(vy)[:, None]
    stress = np.zeros((T, 7, 1))
    stress[:, :5, 0] = peak * shape * (1 - r / 5)[None]
    stress[:, 5:, 0] = 0.5 * peak * shape
    plate = np.array([True] * 5 + [False] * 2)
    return pos, stress, plate


def test_impact_metrics_read_known_errors():
    tp, ts, plate = _impact()
    m = impact_metrics(tp, ts, tp, ts, plate)
    assert m.rebound_agrees and m.solver_rebounds and m.peak_plate_stress_error_pct == 0
    assert m.peak_plate_frame_error == 0 and m.max_deflection_error_pct == 0 and m.far_deflection_error_um == 0
    pp, ps, _ = _impact(rebound=False, peak_frame=13, peak=90.0, defl=0.06)
    m = impact_metrics(pp, ps, tp, ts, plate)
    assert not m.model_rebounds and not m.rebound_agrees
    assert m.peak_plate_stress_error_pct == pytest.approx(-10.0)
    assert m.peak_ball_stress_error_pct == pytest.approx(-10.0)
    assert m.peak_plate_frame_error == 3
    assert m.max_deflection_error_pct == pytest.approx(20.0)
    assert m.far_deflection_error_um > 0


def test_summarize_impact_medians_percentiles_and_the_signed_worst():
    rows = [
        fake_metrics(
            rebound_agrees=a,
            model_rebounds=a,
            solver_rebounds=True,
            peak_plate_stress_error_pct=e,
            peak_plate_frame_error=f,
            far_deflection_error_um=1.0,
            far_deflection_error_pct=2.0,
        )
        for a, e, f in [(True, -30.0, 1), (True, 10.0, -2), (False, 5.0, 0), (True, -1.0, 4)]
    ]
    s = summarize_impact(rows)
    assert s.rebound_agreement == 0.75 and s.model_rebounds == 3 and s.solver_rebounds == 4
    e = s.peak_plate_stress_error_pct
    assert e.median_abs == 7.5 and e.median == 2.0 and e.worst == -30.0
    assert e.p90_abs == pytest.approx(np.percentile([30, 10, 5, 1], 90))
    assert s.peak_plate_frame_error.worst == 4
    assert s.far_deflection_error_um.median == 1.0 and s.far_deflection_error_pct.worst == 2.0


def test_evaluate_reports_physics_and_errors_by_body(data, tmp_path, tiny_config):
    train(tiny_config(*EXTRA), data, "mgn", tmp_path / "run", progress=False)
    m = evaluate(Run.load(tmp_path / "run", "cpu"), data, "test")
    p = m.physics
    assert p is not None and p.trajectories == 1 and 0 <= p.rebound_agreement <= 1
    assert set(m.error_by_step) == {f"{q}_{g}" for q in ("position", "stress") for g in ("ball", "contact", "far")}
    assert len(m.error_by_step["position_far"]) == FRAMES - 2
    saved = json.loads((tmp_path / "run" / "metrics_test.json").read_text())
    assert saved["physics"] == p.to_json() and "physics" in saved["per_trajectory"][0]


# -- sweeps ------------------------------------------------------------------------------------------------------
def test_trend_and_limit_call():
    assert sw.trend([1.0, 2.0, 3.0]) == {"sign": 1, "monotonic": True, "change_pct": 200.0}
    assert sw.trend([3.0, 1.0, 2.0])["monotonic"] is False
    assert sw.trend([2.0, 2.0, 2.0])["sign"] == 0
    x = np.array([0.5, 0.6, 0.7, 0.8, 0.9])
    thick = sw.limit_call(x, np.array([900, 800, 720, 690, 650]), 703)  # thicker is safer
    assert thick["side"] == "minimum" and thick["call"] == 0.8 and thick["passing"] == [0.8, 0.9]
    high = sw.limit_call(x, np.array([600, 650, 700, 710, 800]), 703)  # higher drops fail
    assert high["side"] == "maximum" and high["call"] == 0.7
    assert sw.limit_call(x, np.full(5, 100.0), 703)["side"] == "all pass"


@pytest.mark.parametrize(
    "text,message",
    [
        ("thickness=0.5:1.0", "PARAM=LO:HI:N"),
        ("thick=0.5:1:3", "unknown parameter"),
        ("thickness=1:0.5:3", "LO < HI"),
        ("thickness=0.5:1:1", "between 2"),
        ("thickness=0.5:inf:3", "finite"),
    ],
)
def test_bad_vary_is_refused_in_one_line(text, message):
    with pytest.raises(ValueError, match=message):
        sw.parse_vary(text)


def test_sweep_with_an_impossible_point_is_refused_before_any_work(data, tmp_path, capsys, tiny_config):
    train(tiny_config(*EXTRA), data, "mgn", tmp_path / "run", progress=False)
    rc = cli(
        [
            "sweep",
            str(tmp_path / "run"),
            "--vary",
            "thickness=-0.5:1:3",
            "--device",
            "cpu",
            "--out",
            str(tmp_path / "out"),
        ]
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "thickness=-0.5" in err[0] and "must be > 0" in err[0]
    assert not (tmp_path / "out").exists()


def test_sweep_cli_verifies_trends_and_the_limit(data, tmp_path, capsys, tiny_config):
    train(tiny_config(*EXTRA), data, "mgn", tmp_path / "run", progress=False)
    rc = cli(
        [
            "sweep",
            str(tmp_path / "run"),
            "--vary",
            "thickness=0.6:1.2:3",
            "--design",
            "drop_height=700",
            "--verify",
            "--yield-mpa",
            "300",
            "--device",
            "cpu",
            "--no-progress",
            "--threads",
            "1",
            "--out",
            str(tmp_path / "out"),
            "--json",
            str(tmp_path / "s.json"),
            "--csv",
            str(tmp_path / "s.csv"),
        ]
    )
    captured = capsys.readouterr()
    assert rc == 0, captured.err
    assert "thickness = 1.2 is outside the model's training data" in captured.err  # range warning once
    out = json.loads((tmp_path / "s.json").read_text())
    assert [d["design"]["thickness"] for d in out["designs"]] == [0.6, 0.9, 1.2]
    assert all("verify" in d for d in out["designs"])
    s = out["sweep"]
    solver = [d["verify"]["solver_peak_plate_stress_mpa"] for d in out["designs"]]
    assert s["trend"]["peak_plate_stress_mpa"]["solver"]["sign"] == int(np.sign(solver[-1] - solver[0]))
    assert s["limit"]["solver"]["passing"] == [t for t, p in zip([0.6, 0.9, 1.2], solver) if p < 300]
    assert (tmp_path / "out" / "sweep_thickness.png").stat().st_size > 0


def test_threads_option_sets_torchs_pool(tmp_path, capsys):
    before = torch.get_num_threads()
    try:
        assert set_threads(1) == 1 and torch.get_num_threads() == 1
        assert 1 <= auto_threads() <= torch.get_num_interop_threads() + 1024
    finally:
        torch.set_num_threads(before)
    # one error line naming the flag and its bound, status 2
    assert cli(["evaluate", str(tmp_path), "--data", str(tmp_path), "--threads", "zero"]) == 2
    err = capsys.readouterr().err
    assert "--threads: expected a whole number from 1 to" in err and len(err.strip().splitlines()) == 1


# -- the authors' training loop ----------------------------------------------------------------------------------
def test_keras_epsilon_hat_adam_equals_the_keras_update():
    g = torch.Generator().manual_seed(0)
    theta0 = torch.randn(5, generator=g, dtype=torch.float64)
    grads = [torch.randn(5, generator=g, dtype=torch.float64) * 1e-6 for _ in range(4)]  # ε matters at this scale
    p = torch.nn.Parameter(theta0.clone())
    opt = torch.optim.Adam([p], lr=1e-3, eps=1e-7)
    lr, b1, b2, eps_hat = 1e-3, 0.9, 0.999, 1e-7
    theta, m, v = theta0.clone(), torch.zeros(5, dtype=torch.float64), torch.zeros(5, dtype=torch.float64)
    for t, grad in enumerate(grads, start=1):
        opt.param_groups[0]["eps"] = keras_epsilon(eps_hat, b2, t)
        p.grad = grad.clone()
        opt.step()
        m, v = b1 * m + (1 - b1) * grad, b2 * v + (1 - b2) * grad**2  # Keras (TF2 optimizer) update
        theta = theta - lr * (1 - b2**t) ** 0.5 / (1 - b1**t) * m / (v.sqrt() + eps_hat)
    torch.testing.assert_close(p.detach(), theta, rtol=1e-12, atol=1e-15)
    plain = torch.nn.Parameter(theta0.clone())  # PyTorch's ε form differs visibly: the option is not vacuous
    opt2 = torch.optim.Adam([plain], lr=1e-3, eps=1e-7)
    for grad in grads:
        plain.grad = grad.clone()
        opt2.step()
    assert (plain.detach() - theta).abs().max() > 1e-6


def _trainer(cfg, data, out, model="hcmt"):
    return Trainer(cfg, data, model, out, seed=0, resume=False, device="cpu", progress=False)


def test_official_loop_options_normalizers_and_loss(data, tmp_path, tiny_config):
    warm = _trainer(
        tiny_config(*EXTRA, "train.normalizer_steps=2", "train.normalizer_warmup=nodes"), data, tmp_path / "a"
    )
    batch = collate_samples([warm.frames[0]])
    warm.step(*batch)
    m = warm.model
    assert m.node_normalizer.count > 0 and m.mesh_normalizer.count == 0 and m.output_normalizer.count == 0
    # mesh edges twice: level 0's rows enter the mesh normalizer once more
    once = _trainer(tiny_config(*EXTRA, "train.normalizer_steps=0"), data, tmp_path / "b")
    twice = _trainer(
        tiny_config(*EXTRA, "train.normalizer_steps=0", "train.mesh_edges_twice=true"), data, tmp_path / "c"
    )
    graph = batch[0]
    assert graph.level_edges  # HCMT with a hierarchy: the option applies
    l_once, _ = once.step(*batch)
    twice.step(*batch)
    extra = graph.mesh_features.shape[0]
    assert float(twice.model.mesh_normalizer.count - once.model.mesh_normalizer.count) == extra
    torch.testing.assert_close(
        twice.model.mesh_normalizer.sum - once.model.mesh_normalizer.sum, graph.mesh_features.double().sum(0)
    )
    # loss over N nodes (the authors') against over the unmasked entries (hcmt): same error, other denominator
    nodes = _trainer(
        tiny_config(*EXTRA, "train.normalizer_steps=0", "train.loss_denominator=nodes"), data, tmp_path / "d"
    )
    l_nodes, _ = nodes.step(*batch)
    mask = batch[2]
    assert l_nodes == pytest.approx(l_once * float(mask.sum()) / graph.num_nodes, rel=1e-5)


def test_deformation_features_are_the_edges_strain_and_zero_at_rest(data):
    adapter = config_adapter(Config.from_dict({"dataset": "impact_plate", "model": {"deformation": True}}))
    plain = get_adapter("impact_plate")
    assert adapter.widths()["mesh_in"] == plain.widths()["mesh_in"] + 3
    ds = FrameDataset(data, "train", plain, 1, True, 0.4)
    tr = ds.trajectory(0)
    mesh = tr.static["mesh_pos"]
    feats = torch.zeros(tr.num_nodes, 3)
    rest = frame_graph(feats, mesh, mesh.clone(), tr.hierarchy, 0.4, deformation=True)
    assert rest.mesh_features.shape[1] == adapter.widths()["mesh_in"]
    assert rest.mesh_features[:, 6:].abs().max() == 0 and all(f[:, 6:].abs().max() == 0 for f in rest.level_features)
    moved = mesh.clone()
    moved[:, 1] += 1e-3 * mesh[:, 0] ** 2  # a bent plate
    g = frame_graph(feats, mesh, moved, tr.hierarchy, 0.4, deformation=True)
    s, r = g.mesh_edges
    torch.testing.assert_close(g.mesh_features[:, 6:8], (moved[s] - moved[r]) - (mesh[s] - mesh[r]))
    torch.testing.assert_close(
        g.mesh_features[:, 8], (moved[s] - moved[r]).norm(dim=1) - (mesh[s] - mesh[r]).norm(dim=1)
    )
    with pytest.raises(ValueError, match="deformation.*dimension"):
        config_adapter(Config.from_dict({"dataset": "sphere_simple", "model": {"deformation": True}}))
