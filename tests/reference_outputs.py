"""Stored reference outputs of every model (the safety net of refactors): HCMT in both attention modes, MGN and GT
on one fixed graph (:func:`models_grid.grid_graph`, seed 0), each model built with ``torch.manual_seed(0)``; the
output of a forward pass that accumulates the normalizers, then the gradients of one loss ``mean(output²)``.

    python tests/reference_outputs.py      # rewrite tests/data/reference_outputs.pt (only after an intended change)

tests/models/test_reference_outputs.py compares the current code against the stored file.
"""

from __future__ import annotations

from pathlib import Path

import torch

from hcmt.models import build_model
from models_grid import grid_graph

PATH = Path(__file__).resolve().parent / "data" / "reference_outputs.pt"
# label -> build_model arguments (node_in 5, mesh_in 6, contact_in 3, out 3 as models_grid's graph)
MODELS = {
    "hcmt-paper": dict(name="hcmt", levels=2, L_C=1, hidden=16, heads=2, attention="paper"),
    "hcmt-official": dict(name="hcmt", levels=2, L_C=1, hidden=16, heads=2, attention="official", ffn_bias=False),
    "mgn": dict(name="mgn", blocks=3, hidden=16),
    "gt": dict(name="gt", blocks=3, hidden=16, heads=2),
}


def graph():
    return grid_graph(9, 9, levels=2, node_in=5, contacts=12, seed=0)


def compute(label: str) -> dict[str, torch.Tensor]:
    """``{"output": [N, 3], "grad.<parameter>": ...}`` of one model on the reference graph (float64)."""
    args = dict(MODELS[label])
    torch.manual_seed(0)
    model = build_model(args.pop("name"), 5, 6, 3, 3, **args).double()
    g = graph()
    g = type(g)(
        **{
            k: (
                v.double()
                if torch.is_tensor(v) and v.is_floating_point()
                else [t.double() if t.is_floating_point() else t for t in v]
                if isinstance(v, list)
                else v
            )
            for k, v in vars(g).items()
        }
    )
    model.train()
    out = model(g, accumulate=True)
    (out**2).mean().backward()
    result = {"output": out.detach()}
    result.update({f"grad.{n}": p.grad.detach().clone() for n, p in model.named_parameters() if p.grad is not None})
    return result


def main() -> None:
    PATH.parent.mkdir(parents=True, exist_ok=True)
    torch.save({label: compute(label) for label in MODELS}, PATH)
    print(f"wrote {PATH}")


if __name__ == "__main__":
    main()
