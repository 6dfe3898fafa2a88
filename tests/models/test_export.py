"""The ahead-of-time compiled forward (:mod:`hcmt.models.export`): the dummy node and contact edges change no real
node's output, for every model; the AOTInductor package agrees with eager on meshes of other sizes and contact counts
(none included), and a second process-like call loads it from the cache instead of exporting again."""

from __future__ import annotations

import pytest
import torch

from hcmt.graph.batch import collate
from hcmt.models import build_model, export as export_module
from hcmt.models.base import resolve_compile
from hcmt.models.export import exported_forward, with_dummies
from models_grid import grid_graph

NODE_IN, MESH_IN, CONTACT_IN, OUT = 5, 6, 3, 3
CONFIGS = [
    ("hcmt", dict(levels=2, L_C=1)),
    ("hcmt", dict(levels=2, L_C=1, attention="official", ffn_bias=False)),
    ("mgn", dict(blocks=2)),
    ("gt", dict(blocks=2)),
]


def make(name, **kw):
    torch.manual_seed(0)
    return build_model(name, NODE_IN, MESH_IN, CONTACT_IN, OUT, hidden=32, heads=4, **kw).eval()


@pytest.mark.parametrize("name,kw", CONFIGS, ids=["hcmt", "hcmt-official", "mgn", "gt"])
@pytest.mark.parametrize("contacts", [0, 5])
def test_dummy_node_and_contact_edges_change_no_real_output(name, kw, contacts):
    model = make(name, **kw)
    levels = kw.get("levels", 0)
    graph = collate([grid_graph(6, 7, levels=levels, node_in=NODE_IN, contacts=contacts, seed=s) for s in (1, 2)])
    padded = with_dummies(graph)
    assert padded.num_nodes == graph.num_nodes + 1 and padded.contact_edges.shape[1] == graph.contact_edges.shape[1] + 2
    with torch.no_grad():
        torch.testing.assert_close(
            model(padded, accumulate=False)[: graph.num_nodes], model(graph, accumulate=False), rtol=1e-6, atol=1e-6
        )


@pytest.mark.slow
@pytest.mark.skipif(
    resolve_compile("auto", steps=10**9, device=torch.device("cpu")) == "none",
    reason="Inductor has no C++ compiler here",
)
def test_exported_forward_agrees_with_eager_and_is_built_once(tmp_path, monkeypatch):
    monkeypatch.setenv("TORCHINDUCTOR_CACHE_DIR", str(tmp_path))
    model = make("mgn", blocks=1)  # the mechanism, at the least compile time (the shipped HCMT: forward_modes.py)
    graphs = [
        collate([grid_graph(n, n + 1, levels=0, node_in=NODE_IN, contacts=c, seed=n)])
        for n, c in ((7, 6), (9, 9), (8, 0), (6, 1))
    ]
    forward = exported_forward(model, graphs[0])
    assert len(list((tmp_path / "aoti").glob("*.pt2"))) == 1
    with torch.no_grad():
        for g in graphs:
            torch.testing.assert_close(forward(g), model(g, accumulate=False), rtol=1e-5, atol=1e-5)
    monkeypatch.setattr(export_module.torch.export, "export", lambda *a, **k: pytest.fail("exported again"))
    again = exported_forward(model, graphs[1])  # another process would find the package: no export, no compile
    torch.testing.assert_close(again(graphs[2]), forward(graphs[2]))


def test_auto_on_the_cpu_is_aot_where_the_package_is_built_or_the_rollouts_are_long(tmp_path, monkeypatch):
    """``--compile auto`` of rollouts on the CPU: ``aot`` once this model's package is on the machine (any length:
    it loads in milliseconds) or for rollouts long enough to compile; short rollouts without a package, the lpe
    ablation and explicit modes are :func:`resolve_compile`'s."""
    from hcmt.inference.rollout import rollout_compile
    from hcmt.models import base
    from hcmt.models.base import AUTO_COMPILE_ROLLOUT_STEPS

    monkeypatch.setenv("TORCHINDUCTOR_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(base.shutil, "which", lambda name: f"/usr/bin/{name}")
    model = make("mgn", blocks=1)
    assert rollout_compile("auto", model, AUTO_COMPILE_ROLLOUT_STEPS) == "aot"
    assert rollout_compile("auto", model, AUTO_COMPILE_ROLLOUT_STEPS - 1) == "none"
    assert rollout_compile("default", model, 1) == "default" and rollout_compile("none", model, 10**6) == "none"
    path = export_module.package_path(model)
    path.parent.mkdir(parents=True)
    path.write_bytes(b"")  # this model's package, built earlier on this machine
    assert rollout_compile("auto", model, 1) == "aot"
    assert rollout_compile("none", model, 1) == "none"
    other = make("mgn", blocks=2)  # another model's key: not built
    assert export_module.package_path(other) != path and rollout_compile("auto", other, 1) == "none"


def test_aot_falls_back_to_torch_compile_with_a_warning_where_the_export_fails(monkeypatch, caplog):
    import hcmt.inference.rollout as rollout_module

    compiled = []
    monkeypatch.setattr(
        rollout_module,
        "exported_forward",
        lambda model, example: (_ for _ in ()).throw(RuntimeError("unsupported op\nmore")),
    )
    monkeypatch.setattr(
        rollout_module, "compile_simulator", lambda model, mode, dynamic: compiled.append((mode, dynamic)) or model
    )
    model = make("mgn", blocks=1)
    graph = collate([grid_graph(5, 6, levels=0, node_in=NODE_IN, contacts=2, seed=3)])
    with caplog.at_level("WARNING", logger="hcmt.inference.rollout"):
        forward = rollout_module.exported(model, graph)
    assert compiled == [("default", True)]
    assert "ahead-of-time export failed (RuntimeError: unsupported op)" in caplog.text
    assert rollout_module.exported(model, graph) is forward  # kept on the model: not tried again
    with torch.no_grad():
        torch.testing.assert_close(forward(graph, accumulate=False), model(graph, accumulate=False))


def test_the_compile_cache_is_hcmts_folder_not_the_temporary_one(tmp_path):
    """Importing the models (which imports torch_geometric, which makes Inductor fix its cache folder) leaves
    Inductor's cache in ``$XDG_CACHE_HOME/hcmt/inductor``, where the docs say; a folder the user set wins."""
    import os
    import subprocess
    import sys

    probe = "import os, hcmt.models, torch_geometric; print(os.environ['TORCHINDUCTOR_CACHE_DIR'])"
    env = {k: v for k, v in os.environ.items() if k != "TORCHINDUCTOR_CACHE_DIR"}
    env.update(XDG_CACHE_HOME=str(tmp_path / "xdg"), TMPDIR=str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()
    out = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == str(tmp_path / "xdg" / "hcmt" / "inductor")
    env["TORCHINDUCTOR_CACHE_DIR"] = str(tmp_path / "mine")
    out = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == str(tmp_path / "mine")


def test_the_one_time_build_announces_itself_and_hides_torchs_future_warnings(tmp_path, monkeypatch, caplog):
    """Before the minute-long build: one warning-level line (shown with ``--no-progress`` too) saying what, why,
    about how long and where; torch's FutureWarnings from inside the export do not reach the user."""
    import warnings

    def export(*args, **kwargs):
        warnings.warn("a deprecation inside torch", FutureWarning)
        raise RuntimeError("stop here")

    monkeypatch.setenv("TORCHINDUCTOR_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(export_module.torch.export, "export", export)
    model = make("mgn", blocks=1)
    graph = collate([grid_graph(5, 6, levels=0, node_in=NODE_IN, contacts=2, seed=3)])
    with caplog.at_level("WARNING", logger="hcmt.models.export"), warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        with pytest.raises(RuntimeError, match="stop here"):
            exported_forward(model, graph)
    assert [r.getMessage() for r in caplog.records] == [
        f"hcmt: compiling MGN's forward once for this machine (torch.export + AOTInductor, about a minute of one "
        f"core), so that every later run loads it in milliseconds; it goes to {export_module.package_path(model)}"
    ]
    assert not [w for w in seen if issubclass(w.category, FutureWarning)]
    assert not list(tmp_path.glob("aoti/*.pt2"))  # a failed build leaves no package
