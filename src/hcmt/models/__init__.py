"""Learned simulators: HCMT (the paper's model), MeshGraphNets and Graph Transformer baselines.

``build_model(name, node_in, mesh_in, contact_in, out, ...)`` makes one; ``build_for_dataset(name, dataset)`` fills
the widths (the dataset's adapter) and the Table 8 depths (its config). Every model maps a :class:`hcmt.graph.batch.Graph` to a
normalized output ``[N, out]`` and owns its normalizers (``normalize_target``, ``denormalize``).
"""
from __future__ import annotations

from .attention import MODES as ATTENTION_MODES, check_mode
from .base import Simulator
from .defaults import DATASET_NAMES, dataset_spec
from .gt import GT
from .hcmt import ABLATIONS, HCMT
from .mgn import MGN
from .normalizer import Normalizer
from .updater import update_positions

MODELS = ("hcmt", "mgn", "gt")


def build_model(name: str, node_in: int, mesh_in: int, contact_in: int, out: int, *, ablation: str | None = None,
                levels: int | None = None, L_C: int | None = None, L_H: int | None = None, hidden: int = 128,
                heads: int = 4, clip: float = 2.0, blocks: int = 15, lpe_k: int = 8, attention: str = "paper",
                ffn_bias: bool = True) -> Simulator:
    """HCMT needs ``levels`` (λ) and ``L_C``; ``L_H`` is optional and must equal ``2λ + 1``.
    MGN and GT use ``blocks``; GT and HCMT use ``heads`` and ``clip``; ``attention`` (``paper`` | ``official``)
    and ``ffn_bias`` are HCMT's (the authors' code: ``official``, no FFN bias)."""
    check_mode(attention)
    name = name.lower()
    if name == "hcmt":
        if levels is None or L_C is None:
            raise ValueError("HCMT needs levels (λ) and L_C (e.g. Impact Plate: levels=6, L_C=2)")
        if L_H is not None and L_H != 2 * levels + 1:
            raise ValueError(f"L_H must be 2λ+1 = {2 * levels + 1} for λ={levels}, got L_H={L_H}")
        return HCMT(node_in, mesh_in, contact_in, out, L_C=L_C, levels=levels, hidden=hidden, heads=heads,
                    clip=clip, ablation=ablation, lpe_k=lpe_k, attention=attention, ffn_bias=ffn_bias)
    if ablation not in (None, "", "none"):
        raise ValueError(f"ablations apply to HCMT only, got ablation={ablation!r} for model {name!r}")
    if name == "mgn":
        return MGN(node_in, mesh_in, contact_in, out, blocks=blocks, hidden=hidden)
    if name == "gt":
        return GT(node_in, mesh_in, contact_in, out, blocks=blocks, heads=heads, hidden=hidden, clip=clip)
    raise ValueError(f"unknown model {name!r}; expected one of {', '.join(MODELS)}")


def build_for_dataset(name: str, dataset: str, **overrides) -> Simulator:
    """``build_model`` with the dataset's widths (Table 9) and depths (Table 8); keywords override them."""
    spec = dataset_spec(dataset)
    kwargs = dict(levels=spec["levels"], L_C=spec["L_C"], L_H=spec["L_H"]) if name.lower() == "hcmt" else {}
    kwargs.update(overrides)
    if "levels" in overrides and "L_H" not in overrides:
        kwargs.pop("L_H", None)
    return build_model(name, spec["node_in"], spec["mesh_in"], spec["contact_in"], spec["out"], **kwargs)


__all__ = ["ABLATIONS", "ATTENTION_MODES", "DATASET_NAMES", "GT", "HCMT", "MGN", "MODELS", "Normalizer", "Simulator", "build_for_dataset",
           "build_model", "dataset_spec", "update_positions"]
