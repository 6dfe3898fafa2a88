"""Learned simulators: HCMT (the paper's model), MeshGraphNets and Graph Transformer baselines.

``build_model(name, node_in, mesh_in, contact_in, out, ...)`` makes one; :data:`REGISTRY` says, per model name, its
display label, whether it needs the mesh hierarchy and whether it returns attention maps;
:func:`hcmt.domains.adapters.build_for_dataset` fills the widths (Table 9) and depths (Table 8) of a dataset. Every
model maps a :class:`hcmt.graph.batch.Graph` to a normalized output ``[N, out]`` and owns its normalizers
(``normalize_target``, ``denormalize``).
"""
from __future__ import annotations

from dataclasses import dataclass

from hcmt.config import MODELS, ModelConfig
from hcmt.errors import InputError

from .attention import MODES as ATTENTION_MODES, check_mode
from .base import Simulator, resolve_device
from .gt import GT
from .hcmt import ABLATIONS, HCMT
from .mgn import MGN
from .normalizer import Normalizer


@dataclass(frozen=True)
class ModelInfo:
    """What the rest of hcmt needs to know of a model without building it."""

    label: str  # the display label everywhere (tables, legends, titles)
    needs_hierarchy: bool  # HCMT: the mesh hierarchy (unless an ablation drops it)
    has_attention: bool  # has attention maps (hcmt.models.attention.recording)
    settings: tuple[str, ...]  # the ModelConfig keys it is built from (its constructor arguments besides widths)


#: one table of the models: name (:data:`hcmt.config.MODELS`, in its order) -> :class:`ModelInfo`
REGISTRY: dict[str, ModelInfo] = dict(zip(MODELS, (
    ModelInfo("HCMT", True, True, ("ablation", "levels", "L_C", "hidden", "heads", "clip", "attention", "ffn_bias")),
    ModelInfo("MGN", False, False, ("hidden", "blocks")),
    ModelInfo("GT (Graph Transformer)", False, True, ("hidden", "blocks", "heads", "clip")),  # not "ground truth"
)))
WIDTHS = ("node_in", "mesh_in", "contact_in", "out")


def architecture(args: dict) -> dict:
    """The constructor arguments (run.yaml's ``model``) the model uses: name, widths and its own settings (older
    runs saved every model's settings, e.g. an MGN run HCMT's ``levels``)."""
    keep = ("name", *WIDTHS, *REGISTRY[args["name"]].settings)
    return {k: args[k] for k in keep if k in args}


_M = ModelConfig  # the schema's defaults are the defaults (hcmt.config)


def build_model(name: str, node_in: int, mesh_in: int, contact_in: int, out: int, *, ablation: str | None = None,
                levels: int = _M.levels, L_C: int = _M.L_C, hidden: int = _M.hidden, heads: int = _M.heads,
                clip: float = _M.clip, blocks: int = _M.blocks, lpe_k: int = 8, attention: str = _M.attention,
                ffn_bias: bool = _M.ffn_bias) -> Simulator:
    """HCMT uses ``levels`` (λ; its HMT has ``L_H = 2λ + 1`` blocks) and ``L_C``; MGN and GT use ``blocks``; GT and
    HCMT use ``heads`` and ``clip``; ``ablation``, ``attention`` (``paper`` | ``official``) and ``ffn_bias`` are
    HCMT's (the authors' code: ``official``, no FFN bias). The defaults are :class:`hcmt.config.ModelConfig`'s."""
    check_mode(attention)
    name = name.lower()
    if name == "hcmt":
        return HCMT(node_in, mesh_in, contact_in, out, L_C=L_C, levels=levels, hidden=hidden, heads=heads,
                    clip=clip, ablation=ablation, lpe_k=lpe_k, attention=attention, ffn_bias=ffn_bias)
    if ablation not in (None, "", "none"):
        raise InputError(f"ablations apply to HCMT only, got ablation={ablation!r} for model {name!r}")
    if name == "mgn":
        return MGN(node_in, mesh_in, contact_in, out, blocks=blocks, hidden=hidden)
    if name == "gt":
        return GT(node_in, mesh_in, contact_in, out, blocks=blocks, heads=heads, hidden=hidden, clip=clip)
    raise InputError(f"unknown model {name!r}; expected one of {', '.join(MODELS)}")


def make_model(args: dict) -> Simulator:
    """A model from its saved constructor arguments (``run.yaml``'s ``model``, a checkpoint's ``model_args``)."""
    args = architecture(args)  # older runs hold other models' settings and L_H (null or 2λ + 1)
    return build_model(args.pop("name"), args.pop("node_in"), args.pop("mesh_in"), args.pop("contact_in"),
                       args.pop("out"), **args)


def from_checkpoint(state: dict) -> Simulator:
    """A model in eval mode from a saved state ``{"model_args": constructor arguments, "model": state dict}`` (a
    training checkpoint or a shipped model; fp16 tensors of a shipped model are cast back to the model's dtype)."""
    model = make_model(state["model_args"])
    ref = model.state_dict()
    model.load_state_dict({k: v.to(ref[k].dtype) for k, v in state["model"].items()})
    return model.eval()


def checkpoint_state(model: Simulator, args: dict, **extra) -> dict:
    """What :func:`from_checkpoint` reads: the constructor arguments and the state dict (plus ``extra``)."""
    return {"model_args": args, "model": model.state_dict(), **extra}


def uses_hierarchy(args: dict, remesh: bool = True) -> tuple[int, bool]:
    """(levels, remesh) of the hierarchy a model of constructor arguments ``args`` needs, built with the run's
    ``data.remesh`` (``remesh``: Delaunay remeshing, or 2-hop edges); MGN and GT need none, only-cmt none either."""
    if not REGISTRY[args["name"]].needs_hierarchy or args.get("ablation") == "only-cmt":
        return 0, True
    return int(args["levels"]), bool(remesh)


__all__ = ["ABLATIONS", "ATTENTION_MODES", "GT", "HCMT", "MGN", "MODELS", "REGISTRY", "ModelInfo", "Normalizer",
           "Simulator", "architecture", "build_model", "checkpoint_state", "from_checkpoint", "make_model",
           "resolve_device", "uses_hierarchy"]
