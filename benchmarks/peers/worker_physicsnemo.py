"""PhysicsNeMo's MeshGraphNet (``nvidia-physicsnemo``, PyG backend) on the exported graph.

    python benchmarks/peers/worker_physicsnemo.py GRAPH.npz

Paper settings (15 blocks, hidden 128, two-layer MLPs with LayerNorm). PhysicsNeMo's MeshGraphNet has one edge
set, so it gets the level-0 mesh edges and the contact edges together (hcmt's MGN keeps them as two sets, each with
its own edge MLP: the same messages, a wider node MLP); contact features are zero-padded to the mesh features'
width. Train step: forward, MSE, backward, Adam (lr 1e-4); inference: a no-grad forward in eval mode. FLOPs of
one train step and one inference counted with ``torch.utils.flop_counter`` (matmuls only)."""

from __future__ import annotations

import importlib.util
import sys
import tempfile
import types
from pathlib import Path

from protocol import one_thread, serve, warm_up

one_thread()

import numpy as np  # noqa: E402
import torch  # noqa: E402
from torch.utils.flop_counter import FlopCounterMode  # noqa: E402


class _Placeholder(types.ModuleType):
    """A module whose every name is an empty class (enough for imports and subclassing, never used here)."""

    def __getattr__(self, name):
        if name.startswith("__"):
            raise AttributeError(name)
        return type(name, (), {})


# torchvision (pulled in by timm for the Swin/DiT layers only) has no CPU build for this torch: placeholders
for _name in ("physicsnemo.nn.module.transformer_layers", "physicsnemo.nn.module.dit_layers"):
    sys.modules[_name] = _Placeholder(_name)


def scatter_backend() -> str:
    """``torch_scatter`` when installed; else (it builds from source for minutes) a stand-in package whose
    ``scatter`` is ``torch_geometric.utils.scatter`` (torch's own scatter-reduce, as hcmt's MGN uses), with the
    metadata PhysicsNeMo's version check reads. MeshGraphNet calls only ``torch_scatter.scatter``."""
    if importlib.util.find_spec("torch_scatter") is not None:
        import torch_scatter

        return f"torch_scatter {torch_scatter.__version__}"
    root = Path(tempfile.mkdtemp(prefix="scatter-shim-"))
    (root / "torch_scatter").mkdir()
    (root / "torch_scatter" / "__init__.py").write_text("from torch_geometric.utils import scatter  # noqa\n")
    (root / "torch_scatter-0.0.0.dist-info").mkdir()
    (root / "torch_scatter-0.0.0.dist-info" / "METADATA").write_text(
        "Metadata-Version: 2.1\nName: torch_scatter\nVersion: 0.0.0\n"
    )
    sys.path.insert(0, str(root))
    return "stand-in: torch_geometric.utils.scatter (torch_scatter not installed)"


def contestant(path: str):
    scatter = scatter_backend()
    import physicsnemo
    from physicsnemo.models.meshgraphnet import MeshGraphNet
    from torch_geometric.data import Data

    torch.set_num_threads(1)
    torch.manual_seed(0)
    d = np.load(path)
    width = d["mesh_features"].shape[1]
    contact = np.pad(d["contact_features"], ((0, 0), (0, width - d["contact_features"].shape[1])))
    edges = torch.from_numpy(np.concatenate([d["mesh_edges"], d["contact_edges"]], 1))
    efeat = torch.from_numpy(np.concatenate([d["mesh_features"], contact], 0))
    nfeat = torch.from_numpy(d["node_features"])
    graph = Data(edge_index=edges, num_nodes=len(nfeat))
    target = torch.randn(len(nfeat), int(d["out_dim"]))
    model = MeshGraphNet(nfeat.shape[1], width, int(d["out_dim"]), processor_size=15, hidden_dim_processor=128)
    opt = torch.optim.Adam(model.parameters(), lr=1e-4)

    def train():
        model.train()
        loss = (model(nfeat, efeat, graph) - target).square().mean()
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()

    def infer():
        model.eval()
        with torch.no_grad():
            model(nfeat, efeat, graph)

    info = {
        "framework": f"PhysicsNeMo {physicsnemo.__version__} (torch {torch.__version__})",
        "model": "mgn",
        "mode": "eager",
        "scatter": scatter,
        "parameters": sum(p.numel() for p in model.parameters()),
        "nodes": len(nfeat),
    }
    warm_up(info, train, infer, lambda: FlopCounterMode(display=False))
    return train, infer, info


if __name__ == "__main__":
    serve(*contestant(sys.argv[1]))
