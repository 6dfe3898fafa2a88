"""The hierarchy's shortcut (paper Fig. 2) and a forward/backward pass on a paper-size Impact Plate sample."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch

from hcmt.domains.spec import build_for_dataset, dataset_spec
from models_grid import hop_distance, paper_graph

pytestmark = pytest.mark.slow  # paper-size models


@pytest.fixture(scope="module")
def sample():
    return paper_graph(seed=0, levels=6)


def _response(model, g, source: int) -> torch.Tensor:
    """|output change| per node when the node features of ``source`` are perturbed (float64, eval mode)."""
    model.double().eval()
    bumped = g.node_features.clone()
    bumped[source] += 3.0
    with torch.no_grad():
        return (model(replace(g, node_features=bumped)) - model(g)).abs().amax(1)


def test_hierarchy_reaches_beyond_the_blocks_receptive_field(sample):
    """MGN with L = L_C + L_H = 15 blocks cannot move information more than 15 mesh hops; HCMT with the same 15
    blocks (Impact Plate: L_C = 2, λ = 6) reaches every node of the body, through the pooled levels.

    Without contact edges (the shortcut is the hierarchy's; contact edges only cross between bodies in CMT).
    In float64: the dependence is structural, but at initialization a perturbation shrinks roughly tenfold per
    hop, below float32 resolution after ~15 hops."""
    g = replace(sample, contact_edges=sample.contact_edges[:, :0], contact_features=sample.contact_features[:0])
    g = replace(
        g,
        node_features=g.node_features.double(),
        mesh_features=g.mesh_features.double(),
        contact_features=g.contact_features.double(),
        level_features=[f.double() for f in g.level_features],
    )
    spec = dataset_spec("impact_plate")
    blocks = spec["L_C"] + spec["L_H"]
    assert blocks == 15
    source = 0
    hops = hop_distance(g.mesh_edges, g.num_nodes, source)
    far = torch.from_numpy(np.isfinite(hops) & (hops > blocks))
    assert far.sum() > 500, "the sample needs nodes of the source's body beyond the receptive field"

    torch.manual_seed(0)
    mgn = build_for_dataset("mgn", "impact_plate", hidden=32, blocks=blocks)
    hcmt = build_for_dataset("hcmt", "impact_plate", hidden=32)
    d_mgn, d_hcmt = _response(mgn, g, source), _response(hcmt, g, source)

    assert (d_mgn[torch.from_numpy(hops == blocks)] > 0).any(), "MGN must reach exactly L hops (hop-count sanity)"
    assert (d_mgn[far] == 0).all(), "MGN changed a node beyond its receptive field"
    assert (d_hcmt[far] > 0).all(), "HCMT's hierarchy should reach every node of the body"
    unreachable = torch.from_numpy(~np.isfinite(hops))  # the other body: no contact edges, no path at all
    assert unreachable.any() and (d_hcmt[unreachable] == 0).all()


@pytest.mark.parametrize("name", ["hcmt", "mgn", "gt"])
def test_forward_backward_paper_size(sample, name):
    g = sample
    torch.manual_seed(0)
    model = build_for_dataset(name, "impact_plate").train()  # Table 8 depths, hidden 128
    target = torch.randn(g.num_nodes, dataset_spec("impact_plate")["out"])
    out = model(g)
    loss = (out - model.normalize_target(target)).square().mean()
    loss.backward()
    assert out.shape == target.shape and torch.isfinite(out).all() and torch.isfinite(loss)
    grads = [p.grad for p in model.parameters()]
    assert all(gr is not None and torch.isfinite(gr).all() for gr in grads)
