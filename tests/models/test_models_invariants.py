"""Model invariants: permutation equivariance, per-receiver softmax, gradients, batching, empty edge sets."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from hcmt.graph.batch import collate
from hcmt.models import build_model
from hcmt.models.attention import EdgeGatedAttention, propagate, recording
from hcmt.viz.attention import maps_from_model
from models_grid import grid_graph, permute_graph

NODE_IN, MESH_IN, CONTACT_IN, OUT = 5, 6, 3, 3
SMALL = dict(hidden=32, heads=4)

CONFIGS = [
    ("hcmt", dict(levels=2, L_C=1)),
    ("hcmt", dict(levels=2, L_C=1, ablation="late-contact")),
    ("hcmt", dict(levels=2, L_C=1, ablation="only-cmt")),
    ("hcmt", dict(levels=2, L_C=1, ablation="only-hmt")),
    ("hcmt", dict(levels=2, L_C=1, ablation="single-branch")),
    ("hcmt", dict(levels=2, L_C=1, ablation="lpe")),
    ("hcmt", dict(levels=0, L_C=1)),
    ("mgn", dict(blocks=3)),
    ("gt", dict(blocks=3)),
]
# the authors' attention (model.attention: official) and bias-free FFNs, in HCMT and every ablation
CONFIGS += [("hcmt", dict(kw, attention="official", ffn_bias=False)) for n, kw in CONFIGS if n == "hcmt"]
IDS = [
    f"{n}-{kw.get('ablation') or kw.get('levels', '')}{'-official' if kw.get('attention') else ''}" for n, kw in CONFIGS
]
BATCHED = [CONFIGS[0], CONFIGS[7], CONFIGS[8], CONFIGS[9]]  # HCMT, MGN, GT, HCMT official


def make(name, **kw):
    torch.manual_seed(0)
    return build_model(name, NODE_IN, MESH_IN, CONTACT_IN, OUT, **SMALL, **kw)


def warm(model, graph):
    """Give the normalizers real statistics, then switch to eval (no accumulation, no LPE sign flips)."""
    model.train()
    with torch.no_grad():
        model(graph)
    return model.eval()


@pytest.mark.parametrize(
    "name,kw",
    [c for c in CONFIGS if c[1].get("ablation") != "lpe"],
    ids=[i for i, c in zip(IDS, CONFIGS) if c[1].get("ablation") != "lpe"],
)
def test_permutation_equivariance(name, kw):
    g = grid_graph(9, 9, levels=2, node_in=NODE_IN, contacts=12)
    model = warm(make(name, **kw), g)
    gp, perm = permute_graph(g, seed=3)
    with torch.no_grad():
        out, out_p = model(g), model(gp)
    assert out.abs().max() > 1e-3  # the check below is not vacuous
    torch.testing.assert_close(out_p, out[perm], rtol=1e-4, atol=1e-5)


def test_lpe_equivariant_up_to_eigenvector_sign_and_basis():
    """LPE is not equivariant in general (eigenvector signs/bases are arbitrary): the known limitation of LPE.
    It is once the encoding itself is permuted along (checked by pinning the encoding)."""
    g = grid_graph(9, 9, levels=2, node_in=NODE_IN, contacts=12)
    model = warm(make("hcmt", levels=2, L_C=1, ablation="lpe"), g)
    pe = model.lpe.encoding(g.mesh_edges, g.num_nodes)
    gp, perm = permute_graph(g, seed=3)
    model.lpe.encoding = lambda edges, n, batch=None: pe if edges is g.mesh_edges else pe[perm]
    with torch.no_grad():
        torch.testing.assert_close(model(gp), model(g)[perm], rtol=1e-4, atol=1e-5)


def test_attention_weights_sum_to_one_per_receiver_head_and_branch():
    g = grid_graph(9, 9, levels=2, node_in=NODE_IN, contacts=12)
    model = warm(make("hcmt", levels=2, L_C=2), g)
    with torch.no_grad(), recording(model) as maps:
        model(g)
    names = [m.name for m in maps]
    assert names[:4] == ["cmt0.mesh", "cmt0.contact", "cmt1.mesh", "cmt1.contact"]
    assert len(maps) == 4 + model.L_H
    level_edges = [g.mesh_edges, *g.level_edges]
    level_n = [g.num_nodes] + [len(p) for p in g.pool]
    # the contract: each map names its level and carries the very edges its weights belong to
    assert [m.level for m in maps[4:]] == [0, 1, 2, 1, 0]  # hmt.down0, down1, bottom2, up1, up0
    for m in maps:
        expected = g.contact_edges if m.name.endswith(".contact") else level_edges[m.level]
        assert torch.equal(m.edge_index, expected) and m.normalized
        edges, n, w = m.edge_index, level_n[m.level], m.weights
        assert w.shape == (edges.shape[1], 4, 8)
        sums = torch.zeros(n, 4, 8).index_add_(0, edges[1], w)
        has_in = torch.bincount(edges[1], minlength=n) > 0
        torch.testing.assert_close(sums[has_in], torch.ones_like(sums[has_in]))
        assert (w >= 0).all()


def test_propagate_matches_dense_masked_softmax_with_clip():
    """Reference: a dense [N, N, H, d] computation of eqs. 1–3 with a masked softmax."""
    torch.manual_seed(1)
    n, h, d, clip = 6, 2, 3, 0.7
    edges = torch.tensor([[1, 2, 3, 0, 4, 5, 1, 0], [0, 0, 0, 1, 1, 1, 2, 3]])  # node 4, 5 receive nothing
    q, k, v = (torch.randn(n, h, d) * 3 for _ in range(3))
    et, gate = torch.randn(edges.shape[1], h, d), torch.randn(edges.shape[1], h, d)
    out, w = propagate(q, k, v, et, gate, edges, clip)
    j, i = edges
    score = torch.full((n, n, h, d), float("-inf"))
    score[i, j] = (q[i] * k[j] / d**0.5).clamp(-clip, clip) + et
    dense_w = torch.softmax(score, dim=1).nan_to_num(0.0)  # rows without edges -> 0
    torch.testing.assert_close(w, dense_w[i, j])
    g_dense = torch.zeros(n, n, h, d)
    g_dense[i, j] = gate
    ref = (dense_w * g_dense * v.unsqueeze(0)).sum(1)
    torch.testing.assert_close(out, ref)
    assert (out[4:] == 0).all()


def test_official_propagate_matches_dense_reference():
    """The authors' formula (yuyudeep/hcmt core_model.py) on dense [N, N, H, d] arrays: no normalization, the edge
    term inside the clip, a plain sum over senders."""
    torch.manual_seed(2)
    n, h, d, clip = 6, 2, 3, 0.7
    edges = torch.tensor([[1, 2, 3, 0, 4, 5, 1, 0], [0, 0, 0, 1, 1, 1, 2, 3]])
    q, k, v = (torch.randn(n, h, d) * 3 for _ in range(3))
    et, gate = torch.randn(edges.shape[1], h, d), torch.randn(edges.shape[1], h, d)
    out, w = propagate(q, k, v, et, gate, edges, clip, mode="official")
    j, i = edges
    mask = torch.zeros(n, n, 1, 1)
    mask[i, j] = 1.0
    e_dense, g_dense = torch.zeros(n, n, h, d), torch.zeros(n, n, h, d)
    e_dense[i, j], g_dense[i, j] = et, gate
    qk = q.unsqueeze(1) * k.unsqueeze(0) / d**0.5  # [i, j, h, d]
    w_dense = torch.exp((e_dense * qk).clamp(-clip, clip)) * mask
    torch.testing.assert_close(w, w_dense[i, j])
    ref = (w_dense * g_dense * v.unsqueeze(0)).sum(1)
    torch.testing.assert_close(out, ref)
    assert (out[4:] == 0).all()
    assert w.min() >= torch.exp(torch.tensor(-clip)) - 1e-6 and w.max() <= torch.exp(torch.tensor(clip)) + 1e-6
    # unlike a softmax, the sum grows with the number of senders: duplicate node 0's edges
    out2, _ = propagate(
        q,
        k,
        v,
        torch.cat([et, et[:3]]),
        torch.cat([gate, gate[:3]]),
        torch.cat([edges, edges[:, :3]], 1),
        clip,
        mode="official",
    )
    torch.testing.assert_close(out2[0], 2 * out[0])
    torch.testing.assert_close(out2[1:], out[1:])


def test_unknown_attention_mode_is_refused():
    with pytest.raises(ValueError, match="model.attention.*'softmx'.*paper, official"):
        make("hcmt", levels=1, L_C=1, attention="softmx")


def test_official_mode_has_bias_free_ffn():
    model = make("hcmt", levels=1, L_C=1, attention="official", ffn_bias=False)
    assert not any(n.endswith("bias") and ".ffn." in n for n, _ in model.named_parameters())
    assert any(n.endswith("bias") and ".ffn." in n for n, _ in make("hcmt", levels=1, L_C=1).named_parameters())


def test_softmax_is_stable_for_huge_edge_terms():
    n, edges = 3, torch.tensor([[1, 2], [0, 0]])
    q = k = v = torch.ones(n, 1, 2)
    et = torch.tensor([[[1e4, -1e4]], [[1e4 + 1.0, -1e4]]])
    out, w = propagate(q, k, v, et, torch.ones(2, 1, 2), edges, 2.0)
    assert torch.isfinite(out).all() and torch.isfinite(w).all()
    torch.testing.assert_close(w[:, 0, 0], torch.softmax(torch.tensor([0.0, 1.0]), 0))


def test_empty_edge_set_contributes_zero():
    att = EdgeGatedAttention(16, 4, 2.0)
    z = torch.randn(5, 16)
    out, w = att(att.project_nodes(z), torch.zeros(0, 16), torch.zeros(2, 0, dtype=torch.long))
    assert out.shape == (5, 16) and (out == 0).all() and w.shape == (0, 4, 4)


@pytest.mark.parametrize("name,kw", CONFIGS, ids=IDS)
def test_zero_contact_edges_run(name, kw):
    g = grid_graph(9, 9, levels=2, node_in=NODE_IN, contacts=0)
    out = make(name, **kw)(g)
    assert out.shape == (g.num_nodes, OUT) and torch.isfinite(out).all()


@pytest.mark.parametrize("name,kw", CONFIGS, ids=IDS)
def test_every_parameter_receives_a_gradient(name, kw):
    g = grid_graph(9, 9, levels=2, node_in=NODE_IN, contacts=12)
    model = make(name, **kw).train()
    model(g).square().mean().backward()
    missing = [n for n, p in model.named_parameters() if p.grad is None or not p.grad.abs().sum() > 0]
    assert not missing, f"no gradient for {missing}"


@pytest.mark.parametrize("name,kw", BATCHED, ids=["hcmt", "mgn", "gt", "hcmt-official"])
def test_batch_of_graphs_equals_graphs_one_by_one(name, kw):
    a = grid_graph(9, 9, levels=2, node_in=NODE_IN, contacts=8, seed=1)
    b = grid_graph(9, 13, levels=2, node_in=NODE_IN, contacts=6, seed=2)
    model = warm(make(name, **kw), a)
    with torch.no_grad():
        batched = model(collate([a, b]))
        torch.testing.assert_close(batched, torch.cat([model(a), model(b)]), rtol=1e-4, atol=1e-5)


def test_normalizers_accumulate_only_when_asked():
    g = grid_graph(5, 5, levels=1, node_in=NODE_IN, contacts=4)
    model = make("hcmt", levels=1, L_C=1)
    model.eval()
    model(g)
    assert model.node_normalizer.count == 0
    model(g, accumulate=True)
    assert model.node_normalizer.count == g.num_nodes
    # one shared mesh normalizer sees the mesh edges of every level
    assert model.mesh_normalizer.count == g.mesh_edges.shape[1] + g.level_edges[0].shape[1]
    model.train()
    model(g)
    assert model.node_normalizer.count == 2 * g.num_nodes
    model(g, accumulate=False)
    assert model.node_normalizer.count == 2 * g.num_nodes


def test_wrong_feature_width_is_refused():
    g = grid_graph(5, 5, levels=1, node_in=NODE_IN + 1)
    with pytest.raises(ValueError, match="node_features"):
        make("mgn", blocks=1)(g)
    g = grid_graph(5, 5, levels=1, node_in=NODE_IN)
    with pytest.raises(ValueError, match="λ=3"):
        make("hcmt", levels=3, L_C=1)(g)


@pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device")
@pytest.mark.parametrize("name,kw", BATCHED, ids=["hcmt", "mgn", "gt", "hcmt-official"])
def test_cuda_matches_cpu(name, kw):
    g = grid_graph(9, 9, levels=2, node_in=NODE_IN, contacts=8)
    model = warm(make(name, **kw), g)
    with torch.no_grad():
        cpu = model(g)
        gpu = model.cuda()(g.to("cuda")).cpu()
    torch.testing.assert_close(gpu, cpu, rtol=1e-3, atol=1e-4)


@pytest.mark.parametrize("name,kw", BATCHED, ids=["hcmt", "mgn", "gt", "hcmt-official"])
def test_activation_checkpointing_gives_the_same_gradients(name, kw):
    g = grid_graph(9, 9, levels=2, node_in=NODE_IN, contacts=12)
    grads = []
    for flag in (False, True):
        model = make(name, **kw).train()
        model.checkpoint_blocks = flag
        model(g, accumulate=False).square().mean().backward()
        grads.append({n: p.grad.clone() for n, p in model.named_parameters()})
    for n in grads[0]:
        torch.testing.assert_close(grads[1][n], grads[0][n], rtol=1e-5, atol=1e-7)


def test_official_attention_maps_are_normalized_per_receiver_for_display():
    g = grid_graph(9, 9, levels=2, node_in=NODE_IN, contacts=12)
    model = warm(make("hcmt", levels=2, L_C=1, attention="official"), g)
    levels = [np.arange(len(g.pool[0]))]  # level-0 index of level-1 nodes: any ids of the right count
    levels.append(np.arange(len(g.pool[1])))
    maps = maps_from_model(model, g)
    assert maps["normalized_for_display"]
    for name, m in maps["matrices"].items():
        rows = np.asarray(m.sum(1)).ravel()
        has = np.diff(m.indptr) > 0
        np.testing.assert_allclose(rows[has], 1.0, rtol=1e-5)


def test_attention_maps_are_recorded_by_hooks_and_forward_returns_the_output_only():
    """hcmt.models.attention.recording: one map per block and branch, named, leveled and with its own edges, for
    HCMT (its single-branch ablation too) and GT; outside the context no hook stays and forward is the output."""
    g = grid_graph(9, 9, levels=2, node_in=NODE_IN, contacts=12)
    for name, kw, names in (
        ("gt", dict(blocks=2), ["gt0", "gt1"]),
        (
            "hcmt",
            dict(levels=1, L_C=1, ablation="single-branch"),
            ["cmt0.mesh+contact", "hmt.down0", "hmt.bottom1", "hmt.up0"],
        ),
    ):
        model = warm(make(name, **kw), g)
        with torch.no_grad(), recording(model) as maps:
            out = model(g)
        assert isinstance(out, torch.Tensor) and [m.name for m in maps] == names
        assert all(m.weights.shape[0] == m.edge_index.shape[1] for m in maps)
        with torch.no_grad():
            model(g)
        assert len(maps) == len(names)  # the hooks are gone
