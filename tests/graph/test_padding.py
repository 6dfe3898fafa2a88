"""Padded graphs (static shapes for compiled steps, ``train.compile``): dummy rows change no output, no gradient,
no normalizer statistic, for every model and both attention modes, on single and batched graphs."""

from __future__ import annotations

import pytest
import torch

from hcmt.graph.batch import PadSizes, bucket, collate, pad_graph
from hcmt.models import build_model
from hcmt.models.base import AUTO_COMPILE_ROLLOUT_STEPS, AUTO_COMPILE_STEPS, compile_simulator, resolve_compile
from models_grid import grid_graph

NODE_IN, MESH_IN, CONTACT_IN, OUT = 5, 6, 3, 3
CONFIGS = [
    ("hcmt", dict(levels=2, L_C=1)),
    ("hcmt", dict(levels=2, L_C=1, attention="official", ffn_bias=False)),
    ("hcmt", dict(levels=2, L_C=1, ablation="late-contact")),
    ("hcmt", dict(levels=2, L_C=1, ablation="single-branch")),
    ("mgn", dict(blocks=3)),
    ("gt", dict(blocks=3)),
]
IDS = ["hcmt", "hcmt-official", "hcmt-late-contact", "hcmt-single-branch", "mgn", "gt"]


def make(name, **kw):
    torch.manual_seed(0)
    return build_model(name, NODE_IN, MESH_IN, CONTACT_IN, OUT, hidden=32, heads=4, **kw)


def loss_and_grads(model, graph, target, real: int):
    """One training step's loss (normalizers accumulating) and the gradient of every parameter."""
    model.train()
    model.zero_grad()
    pred = model(graph, accumulate=True)[:real]
    tgt = model.normalize_target(target, accumulate=True)
    loss = ((pred - tgt) ** 2).mean()
    loss.backward()
    return pred.detach(), {n: p.grad.clone() for n, p in model.named_parameters() if p.grad is not None}


@pytest.mark.parametrize("name,kw", CONFIGS, ids=IDS)
def test_padding_changes_no_output_gradient_or_statistic(name, kw):
    graphs = [
        grid_graph(7, 8, levels=2, node_in=NODE_IN, contacts=9, seed=1),
        grid_graph(6, 9, levels=2, node_in=NODE_IN, contacts=5, seed=2),
    ]
    g = collate(graphs)
    sizes = PadSizes.of(graphs, batch=2)
    padded = pad_graph(g, sizes)
    assert padded.num_nodes == sizes.nodes > g.num_nodes  # padding is really there
    assert padded.contact_edges.shape[1] == bucket(g.contact_edges.shape[1]) > g.contact_edges.shape[1]
    target = torch.randn(g.num_nodes, OUT, generator=torch.Generator().manual_seed(5))
    target_padded = torch.cat([target, torch.zeros(padded.num_nodes - g.num_nodes, OUT)])

    a, b = make(name, **kw), make(name, **kw)
    # the target normalizer of the padded model sees the padded target with the node mask
    b.normalize_target = lambda t, accumulate=None, f=b.normalize_target: f(
        target_padded, accumulate, padded.node_mask
    )[: g.num_nodes]
    out_a, grads_a = loss_and_grads(a, g, target, g.num_nodes)
    out_b, grads_b = loss_and_grads(b, padded, target, g.num_nodes)
    assert out_a.abs().max() > 1e-3  # not vacuous
    torch.testing.assert_close(out_b, out_a, rtol=1e-5, atol=1e-6)
    assert grads_a.keys() == grads_b.keys() and len(grads_a) == len(list(a.parameters()))
    for n in grads_a:
        torch.testing.assert_close(grads_b[n], grads_a[n], rtol=1e-4, atol=1e-6, msg=n)
    for (n, x), (_, y) in zip(a.named_buffers(), b.named_buffers()):  # normalizer statistics of real rows only
        torch.testing.assert_close(y, x, rtol=1e-12, atol=1e-9, msg=n)
    # eval mode, statistics frozen: the same again
    a.eval(), b.eval()
    with torch.no_grad():
        torch.testing.assert_close(b(padded)[: g.num_nodes], a(g), rtol=1e-5, atol=1e-6)


def test_dummy_rows_touch_only_dummy_nodes():
    g = grid_graph(6, 6, levels=2, node_in=NODE_IN, contacts=4, seed=3)
    p = pad_graph(g, PadSizes.of([g]))
    n = g.num_nodes
    for edges, mask in ((p.mesh_edges, p.mesh_mask), (p.contact_edges, p.contact_mask)):
        dummy = edges[:, mask == 0]
        assert dummy.numel() and (dummy == n).all()
        assert (edges[:, mask == 1] < n).all()
    counts = [n] + [int(q.shape[0]) for q in g.pool]
    for l in range(g.num_levels):
        kept = p.pool[l]
        assert (kept[: counts[l + 1]] == g.pool[l]).all() and (kept[counts[l + 1] :] == counts[l]).all()
        assert (p.level_edges[l][:, p.level_masks[l] == 0] == counts[l + 1]).all()


def test_bucket_sizes_and_refusals():
    assert bucket(0) == 64 and bucket(64) == 64 and bucket(65) == 80 and bucket(100) == 112
    sizes = [bucket(n) for n in range(1, 5000)]
    assert all(s >= n and (s <= 64 or s <= 1.25 * n + 1) for n, s in zip(range(1, 5000), sizes))
    assert len(set(sizes)) <= 4 * 7 + 1  # four sizes per octave: few shapes to compile
    g = grid_graph(6, 6, levels=2, node_in=NODE_IN, contacts=4)
    with pytest.raises(ValueError, match="do not fit"):
        pad_graph(g, PadSizes(g.num_nodes, 10_000, PadSizes.of([g]).levels))
    with pytest.raises(ValueError, match="padded already"):
        pad_graph(pad_graph(g, PadSizes.of([g])), PadSizes.of([g]))


@pytest.mark.parametrize(
    "name,kw", CONFIGS + [("hcmt", dict(levels=2, L_C=1, ablation="only-hmt"))], ids=IDS + ["hcmt-only-hmt"]
)
@pytest.mark.parametrize("padded", [False, True], ids=["plain", "padded"])
def test_eager_accumulate_equals_accumulating_forward(name, kw, padded):
    """What a compiled step does (``model.accumulate`` then ``forward`` without accumulation) leaves the same
    statistics and gives the same output as ``forward(accumulate=True)`` + ``normalize_target``."""
    g = grid_graph(7, 7, levels=2, node_in=NODE_IN, contacts=6, seed=4)
    target = torch.randn(g.num_nodes, OUT, generator=torch.Generator().manual_seed(1))
    if padded:
        g = pad_graph(g, PadSizes.of([g]))
        target = torch.cat([target, torch.zeros(g.num_nodes - target.shape[0], OUT)])
    a, b = make(name, **kw).train(), make(name, **kw).train()
    with torch.no_grad():
        out_a = a(g, accumulate=True)
        a.normalize_target(target, accumulate=True, mask=g.node_mask)
        b.accumulate(g, target)
        out_b = b(g, accumulate=False)
    torch.testing.assert_close(out_b, out_a)
    stats = {n: x for n, x in a.named_buffers()}
    assert any(n.endswith("count") and x.item() > 0 for n, x in stats.items())
    for n, y in b.named_buffers():
        assert torch.equal(y, stats[n]), n


def test_compile_helper_holds_the_buckets_and_refuses_unknown_modes(monkeypatch):
    import torch._dynamo

    seen = []
    monkeypatch.setattr(torch, "compile", lambda m, **kw: seen.append(kw) or m)
    model = make("mgn", blocks=1)
    with torch._dynamo.config.patch(recompile_limit=8):  # restored afterwards
        assert compile_simulator(model, "default") is model and seen[0]["dynamic"] is False
        assert compile_simulator(model, "default", dynamic=True) is model and seen[1]["dynamic"] is True
        assert {kw["mode"] for kw in seen} == {None}
        assert torch._dynamo.config.recompile_limit >= 64  # Dynamo would fall back to eager after 8 shapes
    with pytest.raises(ValueError, match="compile mode 'fast'"):
        compile_simulator(model, "fast")


def test_pad_sizes_are_bucket_sizes():
    """Every padded size is a bucket size, so meshes of similar size (other designs) mostly share shapes."""
    a, b = (grid_graph(10, c, levels=2, node_in=NODE_IN, contacts=3) for c in (10, 11))
    sa, sb = PadSizes.of([a]), PadSizes.of([b])
    sizes = [sa.nodes, sa.mesh, *[x for lv in sa.levels for x in lv]]
    assert all(bucket(x) == x for x in sizes)
    assert (sa.nodes, sa.mesh) == (sb.nodes, sb.mesh) and a.num_nodes != b.num_nodes


def test_auto_compile_compiles_only_long_runs_where_a_compiler_exists(monkeypatch):
    """``train.compile: auto`` (the default): a long run is compiled where Inductor has its compiler; a short run,
    the lpe ablation and a machine without a C++ compiler run eager; explicit modes are kept."""
    from hcmt.models import base

    cpu = torch.device("cpu")
    monkeypatch.setattr(base.shutil, "which", lambda name: f"/usr/bin/{name}")
    assert resolve_compile("auto", steps=AUTO_COMPILE_STEPS, device=cpu) == "default"
    assert resolve_compile("auto", steps=AUTO_COMPILE_STEPS - 1, device=cpu) == "none"
    assert resolve_compile("auto", steps=10**6, device=cpu, lpe=True) == "none"
    assert resolve_compile("none", steps=10**6, device=cpu) == "none"
    assert resolve_compile("max-autotune", steps=1, device=cpu) == "max-autotune"
    rollouts = dict(device=cpu, threshold=AUTO_COMPILE_ROLLOUT_STEPS)  # a design check's, an evaluation's
    assert AUTO_COMPILE_ROLLOUT_STEPS < AUTO_COMPILE_STEPS
    assert resolve_compile("auto", steps=AUTO_COMPILE_ROLLOUT_STEPS, **rollouts) == "default"
    assert resolve_compile("auto", steps=AUTO_COMPILE_ROLLOUT_STEPS - 1, **rollouts) == "none"
    monkeypatch.setattr(base.shutil, "which", lambda name: None)
    monkeypatch.delenv("CXX", raising=False)
    assert resolve_compile("auto", steps=10**6, device=cpu) == "none"


@pytest.mark.skipif(
    resolve_compile("auto", steps=10**9, device=torch.device("cpu")) == "none",
    reason="Inductor has no C++ compiler here",
)
def test_dynamic_compile_serves_every_mesh_and_agrees_with_eager():
    """Rollouts compile with symbolic sizes (``dynamic=True``, real Inductor): meshes of other sizes and contact
    counts (none included) reuse the compiled code, and every output agrees with the eager forward to 1e-5."""
    import torch._dynamo

    torch._dynamo.reset()
    model = make("hcmt", levels=1, L_C=1, attention="official", ffn_bias=False).eval()
    net = compile_simulator(model, "default", dynamic=True)
    graphs = [grid_graph(n, n + 1, levels=1, node_in=NODE_IN, contacts=c, seed=n) for n, c in ((7, 6), (9, 9), (8, 0))]
    torch._dynamo.utils.counters.clear()
    with torch.no_grad():
        for g in graphs:
            torch.testing.assert_close(net(g, accumulate=False), model(g, accumulate=False), rtol=1e-5, atol=1e-5)
    # one graph for every size, a second at most for a graph without contact edges (Dynamo specializes 0 and 1)
    assert 1 <= torch._dynamo.utils.counters["stats"]["unique_graphs"] <= 2


@pytest.mark.skipif(
    resolve_compile("auto", steps=10**9, device=torch.device("cpu")) == "none",
    reason="Inductor has no C++ compiler here",
)
def test_compiled_training_on_two_cpu_threads_writes_no_atomic_adds():
    """On several CPU threads, mode ``default`` keeps Inductor's own kernels on one thread (the matmuls use all):
    otherwise it writes the backward of every gather, a scatter-add, with atomic adds, which made the compiled
    training step slower on 2 threads than on one (docs/RESULTS.md). Real Inductor, caches off so the code is
    written here; the gradients agree with eager."""
    import torch._dynamo
    import torch._functorch.config as functorch
    import torch._inductor.config as inductor
    from torch._inductor.utils import run_and_get_code

    class Gather(torch.nn.Module):  # a gather, as every message pass has: its backward is a scatter-add
        def __init__(self):
            super().__init__()
            self.weight = torch.nn.Parameter(torch.randn(50, 8))

        def forward(self, index):
            return torch.tanh(self.weight[index])

    model, index = Gather(), torch.randint(0, 50, (400,), generator=torch.Generator().manual_seed(0))

    def grads(net):
        model.zero_grad()
        net(index).square().sum().backward()
        return [p.grad.clone() for p in model.parameters()]

    threads = torch.get_num_threads()
    try:
        torch.set_num_threads(2)
        with inductor.patch(fx_graph_cache=False), functorch.patch(enable_autograd_cache=False):
            compiled, code = run_and_get_code(grads, compile_simulator(model, "default", dynamic=True))
    finally:
        torch.set_num_threads(threads)
        torch._dynamo.reset()
    assert len(code) >= 2  # forward and backward
    assert not [c for c in code if "atomic_add" in c]
    for a, b in zip(compiled, grads(model)):
        torch.testing.assert_close(a, b, rtol=1e-5, atol=1e-5)
