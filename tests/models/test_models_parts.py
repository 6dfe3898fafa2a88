"""Shared parts: online normalizer, Laplacian PE, updater, factory and the paper's per-dataset table."""

from __future__ import annotations

import io

import numpy as np
import pytest
import torch

from hcmt.config import DATASET_NAMES, ModelConfig
from hcmt.domains.spec import build_for_dataset, dataset_spec
from hcmt.domains.updater import update_positions
from hcmt.models import ABLATIONS, HCMT, build_model
from hcmt.models.lpe import LaplacianPE, laplacian_pe
from hcmt.models.mgn import MGNBlock
from hcmt.models.normalizer import Normalizer


# -- normalizer ----------------------------------------------------------------------------------------------------
def test_normalizer_statistics_match_numpy_over_all_accumulated_rows():
    rng = np.random.default_rng(0)
    batches = [rng.normal(loc=[3.0, -1.0], scale=[2.0, 0.01], size=(n, 2)) for n in (7, 50, 13)]
    norm = Normalizer(2)
    for b in batches:
        norm(torch.tensor(b, dtype=torch.float32), accumulate=True)
    allx = np.concatenate(batches)
    np.testing.assert_allclose(norm.mean().numpy(), allx.mean(0), rtol=1e-5)
    np.testing.assert_allclose(norm.std().numpy(), allx.std(0), rtol=1e-4)
    x = torch.tensor(allx, dtype=torch.float32)
    y = norm(x)
    np.testing.assert_allclose(y.mean(0).numpy(), 0.0, atol=1e-4)
    np.testing.assert_allclose(y.std(0, unbiased=False).numpy(), 1.0, rtol=1e-4)
    torch.testing.assert_close(norm.inverse(y), x, rtol=1e-5, atol=1e-5)


def test_normalizer_stops_after_max_accumulations_and_clamps_std():
    norm = Normalizer(1, max_accumulations=2, std_epsilon=1e-3)
    for v in (1.0, 1.0, 100.0):
        norm(torch.full((4, 1), v), accumulate=True)
    assert norm.count == 8 and norm.mean().item() == 1.0
    assert norm.std().item() == pytest.approx(1e-3)  # constant feature: std clamped to ε
    assert Normalizer(3).std().tolist() == [1.0, 1.0, 1.0]  # nothing seen yet: identity


def test_normalizer_statistics_are_saved_in_the_state_dict():
    model = build_model("mgn", 4, 6, 3, 2, blocks=1, hidden=16)
    model.node_normalizer(torch.randn(10, 4) * 5 + 2, accumulate=True)
    buf = io.BytesIO()
    torch.save(model.state_dict(), buf)
    buf.seek(0)
    clone = build_model("mgn", 4, 6, 3, 2, blocks=1, hidden=16)
    clone.load_state_dict(torch.load(buf))
    torch.testing.assert_close(clone.node_normalizer.mean(), model.node_normalizer.mean())
    torch.testing.assert_close(clone.node_normalizer.std(), model.node_normalizer.std())
    assert any(k.startswith("output_normalizer.") for k in model.state_dict())


def test_normalizer_refuses_wrong_width():
    with pytest.raises(ValueError, match=r"\[rows, 3\]"):
        Normalizer(3)(torch.zeros(4, 2))


# -- Laplacian positional encoding ---------------------------------------------------------------------------------
def _path(n):
    i = np.arange(n - 1)
    return np.concatenate([np.stack([i, i + 1]), np.stack([i + 1, i])], axis=1)


@pytest.mark.parametrize("n", [20, 600])  # dense and shift-invert paths
def test_lpe_of_a_path_matches_the_analytic_spectrum(n):
    """Normalized Laplacian of the path P_n: eigenvalues 1 - cos(πm/(n-1)), eigenvectors D^{1/2}·cos(πm·x/(n-1))."""
    k = 8
    pe = laplacian_pe(_path(n), n, k)
    deg = np.full(n, 2.0)
    deg[[0, -1]] = 1.0
    x = np.arange(n)
    for m in range(1, k + 1):
        ref = np.sqrt(deg) * np.cos(np.pi * m * x / (n - 1))
        ref /= np.linalg.norm(ref)
        assert abs(abs(pe[:, m - 1] @ ref) - 1.0) < 1e-6, m


def test_lpe_pads_small_graphs_and_flips_signs_only_in_training():
    assert np.count_nonzero(laplacian_pe(_path(4), 4, 8)[:, 3:]) == 0
    lpe = LaplacianPE(hidden=8, k=4)
    edges = torch.from_numpy(_path(30))
    lpe.eval()
    fixed = lpe.encoding(edges, 30)
    torch.testing.assert_close(lpe.encoding(edges, 30), fixed)
    lpe.train()
    torch.manual_seed(0)
    draws = [lpe.encoding(edges, 30) for _ in range(8)]
    for d in draws:
        torch.testing.assert_close(d.abs(), fixed.abs())
    assert any(not torch.equal(d, fixed) for d in draws)


def test_lpe_is_computed_per_graph_of_a_batch():
    lpe = LaplacianPE(hidden=8, k=4).eval()
    a, b = torch.from_numpy(_path(12)), torch.from_numpy(_path(30))
    batched = lpe.encoding(torch.cat([a, b + 12], 1), 42, torch.cat([torch.zeros(12), torch.ones(30)]).long())
    torch.testing.assert_close(batched, torch.cat([lpe.encoding(a, 12), lpe.encoding(b, 30)]))


# -- updater -------------------------------------------------------------------------------------------------------
def test_first_order_update_reproduces_uniform_motion():
    x0 = torch.randn(5, 2)
    v = torch.randn(5, 2)
    out = torch.cat([v, torch.randn(5, 1)], 1)  # velocity, stress
    nxt, rest = update_positions(out, x0, order=1)
    torch.testing.assert_close(nxt, x0 + v)
    torch.testing.assert_close(rest, out[:, 2:])


def test_second_order_update_reproduces_constant_acceleration():
    """x(t) = x0 + v t + a t²/2 sampled at t = 0, 1, 2: the per-step acceleration x2 - 2x1 + x0 is a."""
    x0, v, a = torch.randn(4, 3), torch.randn(4, 3), torch.randn(4, 3)
    pos = [x0 + v * t + 0.5 * a * t**2 for t in (0.0, 1.0, 2.0)]
    nxt, rest = update_positions(a, pos[1], pos[0], order=2)
    torch.testing.assert_close(nxt, pos[2])
    assert rest.shape == (4, 0)
    with pytest.raises(ValueError, match="previous_position"):
        update_positions(a, pos[1], order=2)


# -- factory and the paper's tables ----------------------------------------------------------------------------------
def test_table8_depths_are_consistent():
    for name in DATASET_NAMES:
        spec = dataset_spec(name)
        assert spec["L_H"] == 2 * spec["levels"] + 1, name
        assert spec["L_C"] + spec["L_H"] == 15, name  # paper: L = L_C + L_H = 15


def test_table9_widths_of_impact_plate():
    spec = dataset_spec("impact-plate")
    assert (spec["node_in"], spec["mesh_in"], spec["contact_in"], spec["out"]) == (9 + 2 + 1 + 1, 6, 3, 3)
    spec = dataset_spec("sphere_simple")  # cloth: 2-D mesh space, 3-D world
    assert (spec["node_in"], spec["mesh_in"], spec["contact_in"], spec["out"], spec["integration"]) == (12, 7, 4, 3, 2)


def test_build_for_dataset_uses_table8():
    model = build_for_dataset("hcmt", "deforming_plate", hidden=16)
    assert (model.L_C, model.levels, model.L_H, len(model.cmt)) == (10, 2, 5, 10)
    assert len(model.hmt.down) == 2 and len(model.hmt.up) == 2
    assert len(build_for_dataset("mgn", "impact_plate", hidden=16).blocks) == 15
    assert len(build_for_dataset("gt", "impact_plate", hidden=16).layers) == 15
    only_cmt = build_for_dataset("hcmt", "impact_plate", hidden=16, ablation="only-cmt")
    assert len(only_cmt.cmt) == 15 and only_cmt.hmt is None


def test_bad_settings_are_refused():
    with pytest.raises(TypeError, match="L_H"):  # derived from levels, not an argument
        build_model("hcmt", 4, 6, 3, 2, levels=2, L_C=2, L_H=5)
    with pytest.raises(ValueError, match="unknown ablation"):
        build_model("hcmt", 4, 6, 3, 2, levels=1, L_C=1, ablation="bogus")
    with pytest.raises(ValueError, match="divisible"):
        build_model("hcmt", 4, 6, 3, 2, levels=1, L_C=1, hidden=30, heads=4)
    with pytest.raises(ValueError, match="clip"):
        build_model("hcmt", 4, 6, 3, 2, levels=1, L_C=1, clip=0.0)
    with pytest.raises(ValueError, match="unknown model"):
        build_model("gnn", 4, 6, 3, 2)
    with pytest.raises(ValueError, match="HCMT only"):
        build_model("mgn", 4, 6, 3, 2, ablation="lpe")
    default = build_model("hcmt", 4, 6, 3, 2)  # one default for each setting: the config schema's
    m = ModelConfig
    assert (default.levels, default.L_C, default.L_H) == (m.levels, m.L_C, 2 * m.levels + 1)
    assert (HCMT(4, 6, 3, 2).levels, HCMT(4, 6, 3, 2).L_C) == (ModelConfig.levels, ModelConfig.L_C)
    with pytest.raises(ValueError, match="unknown dataset"):
        dataset_spec("flag_simple")
    assert set(ABLATIONS) == {"late-contact", "only-cmt", "only-hmt", "lpe", "single-branch"}
    with pytest.raises(ValueError, match="no remeshing is a graph setting: data.remesh=false"):
        build_model("hcmt", 4, 6, 3, 2, ablation="no-remesh")  # the paper's remeshing ablation is the graph's


def test_mgn_edge_update_equals_the_mlp_of_the_concatenation():
    """MGN's edge MLP takes its first layer split by input blocks (W_e e + (W_s z)_j + (W_r z)_i + b, node terms
    once per node): the outputs and every gradient equal f([e_ij, z_j, z_i]) of the plain concatenation."""
    torch.manual_seed(0)
    block = MGNBlock(hidden=8).double()
    z = torch.randn(7, 8, dtype=torch.float64, requires_grad=True)
    e = torch.randn(12, 8, dtype=torch.float64, requires_grad=True)
    edges = torch.randint(0, 7, (2, 12))
    split = MGNBlock._edge_update(block.mesh_edge, e, z, edges)
    plain = block.mesh_edge(torch.cat([e, z[edges[0]], z[edges[1]]], dim=-1))
    torch.testing.assert_close(split, plain, rtol=1e-12, atol=1e-12)
    weights = torch.randn_like(plain)
    grads = [
        torch.autograd.grad((out * weights).sum(), [z, e, *block.mesh_edge.parameters()]) for out in (split, plain)
    ]
    for a, b in zip(*grads):
        torch.testing.assert_close(a, b, rtol=1e-12, atol=1e-12)
