"""The rollout engine (:func:`hcmt.inference.rollout.rollout_batch`: the batch's static graph merged once, every
step's graph built for all designs at once, the rollout on the model's device) against the loop it replaced
(``old_rollout_batch`` of benchmarks/micro/rollout_engine.py: each design's graph built on the host and collated,
each design integrated in a Python loop): the same graphs field by field, the same rollouts, the diverging design
named."""

import sys
from dataclasses import fields
from pathlib import Path

import numpy as np
import pytest
import torch

from graph_meshes import cloth, plate_and_ball
from hcmt.data.format import NodeType
from hcmt.design.inputs import settings_of
from hcmt.design.prediction import design_trajectory
from hcmt.domains.adapters import get_adapter
from hcmt.domains.frames import input_graph
from hcmt.domains.stepping import batch_input, frame_batch
from hcmt.domains.trajectory import Trajectory, load_split, prepare_static
from hcmt.errors import RolloutError
from hcmt.graph.batch import Graph, collate
from hcmt.graph.build import frame_graph, merge_static, merged_graph
from hcmt.graph.contact import contact_edges
from hcmt.graph.hierarchy import build_hierarchy
from hcmt.inference.rollout import rollout, rollout_batch
from hcmt.inference.run import Run
from hcmt.models import build_model
from hcmt.sim.sampling import sample_design

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
from micro.rollout_engine import old_rollout_batch  # noqa: E402


@pytest.fixture(scope="module")
def shipped():
    """The shipped model and three of its preset's designs (three meshes; the ball within the contact radius of the
    plate from the first frame)."""
    run = Run.load("pretrained:impact_plate_small", "cpu")
    rng = np.random.default_rng(4)
    trajs = [
        design_trajectory(run, f"d{i}", sample_design(rng, run.meta["generator"]["preset"]), settings_of(run.meta))[0]
        for i in range(3)
    ]
    assert len({tr.num_nodes for tr in trajs}) == 3
    return run, trajs


def tiny(name: str, run, **kw):
    """A small untrained ``name`` model of the shipped model's widths, with its input and output statistics (so
    its steps are of the data's scale)."""
    torch.manual_seed(0)
    model = build_model(name, **run.adapter.widths(), hidden=16, heads=2, levels=2, L_C=1, blocks=2, **kw)
    stats = {k: v for k, v in run.model.state_dict().items() if "normalizer" in k}
    model.load_state_dict(stats, strict=False)
    return model.eval()


def sorted_edges(edges: torch.Tensor, feats: torch.Tensor, n: int):
    order = torch.argsort(edges[0] * n + edges[1])
    return edges[:, order], feats[order]


def assert_same_graph(got: Graph, want: Graph, atol: float = 0.0):
    """Field by field: equal indices, features within ``atol`` (contact edges compared sorted)."""
    n = want.num_nodes
    ce, cf = sorted_edges(got.contact_edges, got.contact_features, n)
    we, wf = sorted_edges(want.contact_edges, want.contact_features, n)
    assert torch.equal(ce, we)
    torch.testing.assert_close(cf, wf, rtol=0, atol=atol)
    for f in fields(Graph):
        if f.name in ("contact_edges", "contact_features"):
            continue
        a, b = getattr(got, f.name), getattr(want, f.name)
        if isinstance(b, list):
            assert len(a) == len(b), f.name
            for x, y in zip(a, b):
                torch.testing.assert_close(x, y, rtol=0, atol=atol, msg=f.name)
        elif b is None:
            assert a is None, f.name
        else:
            torch.testing.assert_close(a, b, rtol=0, atol=atol, msg=f.name)


def assert_same_rollouts(got: list[dict], want: list[dict], rel: float = 1e-5):
    """Positions and stress equal to ``rel`` of their scale; the same first predicted frame."""
    assert len(got) == len(want)
    for g, w in zip(got, want):
        assert g["start"] == w["start"] and g["world_pos"].shape == w["world_pos"].shape
        for key in ("world_pos", "stress"):
            if w[key] is None:
                assert g[key] is None, key
                continue
            scale = float(w[key].abs().max()) or 1.0
            torch.testing.assert_close(g[key], w[key], rtol=0, atol=rel * scale, msg=key)


def test_merged_graph_equals_the_collated_graphs_of_the_designs(shipped):
    """One, then three designs of different meshes: the step's graph equals ``collate`` of each design's
    ``input_graph``, at the data's first frames and at displaced positions (other contact edges)."""
    run, trajs = shipped
    for batch in (trajs[:1], trajs):
        fb = frame_batch(batch, 4, "cpu")
        x, prev, nxt = fb.world_pos[1], fb.world_pos[0], fb.world_pos[2]
        moved = x + 0.3 * torch.randn(x.shape, generator=torch.Generator().manual_seed(1))
        for pos in (x, moved):
            got = batch_input(fb, pos, prev, nxt, run.radius)
            parts = [
                input_graph(tr, p, q, r, run.radius)
                for tr, p, q, r in zip(batch, pos.split(fb.sizes), prev.split(fb.sizes), nxt.split(fb.sizes))
            ]
            want = collate(parts)
            assert want.contact_edges.shape[1] > 0 and got.num_levels == 4
            assert_same_graph(got, want)


def test_contact_edges_never_join_two_designs(shipped):
    """Every design starts at the same place: the merged graph's contact edges stay inside one design."""
    run, trajs = shipped
    fb = frame_batch(trajs, 3, "cpu")
    g = batch_input(fb, fb.world_pos[1], fb.world_pos[0], fb.world_pos[2], run.radius)
    assert torch.equal(g.batch[g.contact_edges[0]], g.batch[g.contact_edges[1]])
    assert set(g.batch[g.contact_edges[0]].tolist()) == {0, 1, 2}


def test_the_dense_search_of_a_batch_equals_the_kdtree(shipped):
    """The GPU's search (dense, each row block against its designs' nodes only) finds the KD-tree's edges over a
    batch of nine designs (more nodes than a row block; float64 on the CPU)."""
    run, trajs = shipped
    fb = frame_batch(trajs * 3, 3, "cpu")
    g, x = fb.graph, fb.world_pos[1]
    kw = dict(node_type=g.node_type, type_pairs=run.adapter.contact_types, batch=g.batch)
    want = contact_edges(x, g.object_id, run.radius, method="kdtree", **kw)
    assert x.shape[0] > 2048 and want.shape[1] > 0
    assert torch.equal(contact_edges(x, g.object_id, run.radius, method="dense", **kw), want)


@pytest.mark.parametrize("method", ["kdtree", "dense"])
def test_merged_self_contact_equals_the_collated_graphs(method):
    """Self-contact (cloth): each design's near-on-the-mesh pairs are excluded in the merged numbering; two folded
    cloths of different meshes lying on one another touch only themselves."""
    meshes = [cloth(n) for n in (12, 15)]
    hs = [build_hierarchy(m, c, None, 1) for m, c, _ in meshes]
    mesh = [torch.from_numpy(m).float() for m, _, _ in meshes]
    world = [torch.from_numpy(w).float() for _, _, w in meshes]
    types = [torch.zeros(len(m), dtype=torch.long) for m in mesh]
    feats = [torch.randn(len(m), 3) for m in mesh]
    static = merge_static(hs, mesh, types, "cpu", self_contact=True)
    got = merged_graph(static, torch.cat(feats), torch.cat(world), 0.06, True, contact_method=method)
    want = collate(
        [
            frame_graph(f, m, w, h, 0.06, True, node_type=t, contact_method=method)
            for f, m, w, h, t in zip(feats, mesh, world, hs, types)
        ]
    )
    assert want.contact_edges.shape[1] > 0
    assert_same_graph(got, want)


@pytest.mark.parametrize(
    "name,kw",
    [("hcmt", {}), ("mgn", {}), ("gt", {}), ("hcmt", {"ablation": "lpe"})],
    ids=["hcmt", "mgn", "gt", "hcmt-lpe"],
)
def test_rollouts_equal_the_old_loop(shipped, name, kw):
    """Three designs of different meshes in contact, batched and one at a time: the old loop's positions and
    stress (the batched loops bit for bit on the CPU)."""
    run, trajs = shipped
    model = tiny(name, run, **kw)
    new = rollout_batch(model, run.adapter, trajs, run.radius, steps=4)
    old = old_rollout_batch(model, run.adapter, trajs, run.radius, steps=4)
    assert_same_rollouts(new, old, rel=0.0)
    assert all(torch.equal(n["world_pos"][:2], tr.world_pos[:2]) for n, tr in zip(new, trajs))
    assert not torch.equal(new[0]["world_pos"][2], trajs[0].world_pos[2])
    singles = [old_rollout_batch(model, run.adapter, [tr], run.radius, steps=4)[0] for tr in trajs]
    assert_same_rollouts(new, singles)
    assert_same_rollouts([rollout(model, run.adapter, trajs[1], run.radius, steps=4)], singles[1:2], rel=0.0)


def test_cpu_blocks_and_padded_steps_equal_the_old_loop(shipped, monkeypatch):
    """On the CPU a batch steps in blocks of whole designs (here one design each): the old loop's rollouts, each
    block's design bit for bit as the old loop one at a time; a padded compile mode (the model itself standing in for
    the compiled one) pads every block to sizes that hold the largest and gives the same rollouts."""
    import hcmt.inference.rollout as rollout_module

    run, trajs = shipped
    model = tiny("hcmt", run)  # hidden 16: a budget of 100 * 128 / 16 = 800 nodes holds one design
    monkeypatch.setattr(rollout_module, "CPU_BLOCK_NODES", 100)
    assert [len(b) for b in rollout_module.blocks(trajs, model, torch.device("cpu"))] == [1, 1, 1]
    new = rollout_batch(model, run.adapter, trajs, run.radius, steps=3)
    singles = [old_rollout_batch(model, run.adapter, [tr], run.radius, steps=3)[0] for tr in trajs]
    assert_same_rollouts(new, singles, rel=0.0)
    assert_same_rollouts(new, old_rollout_batch(model, run.adapter, trajs, run.radius, steps=3))
    padded = []
    monkeypatch.setattr(rollout_module, "compiled", lambda m, mode, dynamic: padded.append(dynamic) or m)
    assert_same_rollouts(rollout_batch(model, run.adapter, trajs, run.radius, steps=3, compile="max-autotune"), new)
    assert padded == [False]


def synthetic(adapter_name: str, mesh: dict, frames: int, name: str, fields_: dict, stress: bool) -> Trajectory:
    """A trajectory of ``mesh`` (mesh_pos, cells, node_type, world) whose OBSTACLE nodes move down and the others
    drift a little, frame by frame."""
    adapter = get_adapter(adapter_name)
    static, hierarchy = prepare_static({**mesh, **fields_}, adapter, 1)
    world = torch.from_numpy(np.asarray(mesh["world"], np.float32))
    drift = torch.zeros_like(world)
    drift[:, -1] = torch.where(static["node_type"] == int(NodeType.OBSTACLE), -0.01, 0.002)
    frames_ = torch.stack([world + k * drift for k in range(frames)])
    data_stress = torch.rand(frames, len(world), 1) if stress else None
    return Trajectory(name, static, frames_, data_stress, hierarchy, adapter)


@pytest.mark.parametrize("dataset", ["sphere_simple", "deformable_plate"])
def test_other_datasets_equal_the_old_loop(dataset):
    """Cloth (self-contact, 2-D mesh in 3-D, second order, no stress) and Deformable Plate (no history, a
    prescribed obstacle, the data's stress kept where the model has no stress output)."""
    if dataset == "sphere_simple":
        trajs = [
            synthetic(
                dataset, dict(mesh_pos=m, cells=c, node_type=np.zeros(len(m), np.int64), world=w), 5, f"c{n}", {}, False
            )
            for n, (m, c, w) in ((n, cloth(n)) for n in (12, 15))
        ]
        radius = 0.06
    else:
        meshes = [plate_and_ball(h=h, length=2.0, radius=0.5) for h in (0.1, 0.125)]
        trajs = [
            synthetic(
                dataset,
                dict(m, world=m["mesh_pos"]),
                5,
                f"p{k}",
                {"poisson_ratio": np.full(len(m["mesh_pos"]), 0.3, np.float32)},
                True,
            )
            for k, m in enumerate(meshes)
        ]
        radius = 0.1
    adapter = trajs[0].adapter
    torch.manual_seed(0)
    model = build_model("mgn", **adapter.widths(), hidden=16, blocks=2).eval()
    model.output_normalizer.accumulate(1e-3 * torch.randn(64, adapter.out(adapter.dim)))
    new = rollout_batch(model, adapter, trajs, radius)
    old = old_rollout_batch(model, adapter, trajs, radius)
    assert_same_rollouts(new, old, rel=0.0)
    assert_same_rollouts(new, [old_rollout_batch(model, adapter, [tr], radius)[0] for tr in trajs])
    if dataset == "deformable_plate":
        assert torch.equal(new[1]["stress"], trajs[1].stress) and new[0]["start"] == 1
    else:
        assert new[0]["stress"] is None and new[0]["start"] == 2


def test_a_diverging_design_is_named(shipped):
    """The second of three designs gets a non-finite input: the error names it (and the step), as the old loop's."""
    run, trajs = shipped
    model = tiny("mgn", run)
    bad = [Trajectory(tr.name, dict(tr.static), tr.world_pos, tr.stress, tr.hierarchy, tr.adapter) for tr in trajs]
    bad[1].static["density"] = torch.full_like(bad[1].static["density"], float("nan"))
    with pytest.raises(RolloutError) as new:
        rollout_batch(model, run.adapter, bad, run.radius, steps=3)
    with pytest.raises(RolloutError) as old:
        old_rollout_batch(model, run.adapter, bad, run.radius, steps=3)
    assert str(new.value) == str(old.value)
    assert str(new.value).startswith("trajectory d1: the predicted state became non-finite at step 2 (frame 2 of 5)")


@pytest.mark.slow  # trains two tiny runs
@pytest.mark.parametrize("name", ["hcmt", "mgn"])
def test_trained_runs_on_generated_data_equal_the_old_loop(impact_data, tmp_path, tiny_config, name):
    """Tiny runs trained on the generated dataset: its training designs (several meshes, the ball striking the
    plate) rolled out by the engine, four at a time and one at a time, equal the old loop's."""
    from hcmt.training import train

    train(
        tiny_config("train.steps=2", "train.contact_radius=0.4"),
        impact_data,
        name,
        tmp_path / "run",
        progress=False,
        device="cpu",
    )
    run = Run.load(tmp_path / "run", "cpu")
    levels, remesh = run.hierarchy_spec
    trajs = load_split(impact_data, "train", run.adapter, levels, remesh, limit=4)
    assert len({tr.num_nodes for tr in trajs}) > 1
    fb = frame_batch(trajs, 3, "cpu")
    assert batch_input(fb, fb.world_pos[1], fb.world_pos[0], fb.world_pos[2], run.radius).contact_edges.shape[1]
    new = rollout_batch(run.model, run.adapter, trajs, run.radius)
    assert_same_rollouts(new, old_rollout_batch(run.model, run.adapter, trajs, run.radius), rel=0.0)
    singles = [rollout(run.model, run.adapter, tr, run.radius) for tr in trajs]
    assert_same_rollouts(new, singles)
    assert_same_rollouts(
        singles, [old_rollout_batch(run.model, run.adapter, [tr], run.radius)[0] for tr in trajs], rel=0.0
    )
