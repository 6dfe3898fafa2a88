"""Learned simulators: HCMT (the paper's model), MeshGraphNets and Graph Transformer baselines.

``build_model(name, node_in, mesh_in, contact_in, out, ...)`` makes one; :data:`REGISTRY` says, per model name, its
display label, whether it needs the mesh hierarchy and whether it returns attention maps, as each model declares it
(:mod:`hcmt.models.registry`; adding a model: docs/extending.md);
:func:`hcmt.domains.spec.build_for_dataset` fills the widths (Table 9) and depths (Table 8) of a dataset. Every
model maps a :class:`hcmt.graph.batch.Graph` to a normalized output ``[N, out]`` and owns its normalizers
(``normalize_target``, ``denormalize``).
"""

from __future__ import annotations

from hcmt.config import MODELS, ModelConfig
from hcmt.errors import InputError

from .base import Simulator, resolve_device  # first: it sets Inductor's cache folder before torch_geometric loads

# isort: split
from .attention import MODES as ATTENTION_MODES, check_mode
from .gt import GT
from .hcmt import ABLATIONS, HCMT
from .mgn import MGN
from .normalizer import Normalizer
from .registry import REGISTRY as _REGISTERED, ModelInfo

#: one table of the models, name -> :class:`ModelInfo`, each entry declared by its model class
#: (:func:`hcmt.models.registry.register`), in the order of :data:`hcmt.config.MODELS` (a name there that no model
#: registers fails here, at import)
REGISTRY: dict[str, ModelInfo] = {name: _REGISTERED[name] for name in MODELS}
WIDTHS = ("node_in", "mesh_in", "contact_in", "out")


def architecture(args: dict) -> dict:
    """The constructor arguments (run.yaml's ``model``) the model uses: name, widths and its own settings (older
    runs saved every model's settings, e.g. an MGN run HCMT's ``levels``)."""
    keep = ("name", *WIDTHS, *REGISTRY[args["name"]].settings)
    return {k: args[k] for k in keep if k in args}


_M = ModelConfig  # the schema's defaults are the defaults (hcmt.config)


def build_model(
    name: str,
    node_in: int,
    mesh_in: int,
    contact_in: int,
    out: int,
    *,
    ablation: str | None = None,
    levels: int = _M.levels,
    L_C: int = _M.L_C,
    hidden: int = _M.hidden,
    heads: int = _M.heads,
    clip: float = _M.clip,
    blocks: int = _M.blocks,
    lpe_k: int = 8,
    attention: str = _M.attention,
    ffn_bias: bool = _M.ffn_bias,
) -> Simulator:
    """HCMT uses ``levels`` (λ; its HMT has ``L_H = 2λ + 1`` blocks) and ``L_C``; MGN and GT use ``blocks``; GT and
    HCMT use ``heads`` and ``clip``; ``ablation``, ``attention`` (``paper`` | ``official``) and ``ffn_bias`` are
    HCMT's (the authors' code: ``official``, no FFN bias). The defaults are :class:`hcmt.config.ModelConfig`'s;
    each model gets the arguments its :data:`REGISTRY` entry names."""
    check_mode(attention)
    name = name.lower()
    info = REGISTRY.get(name)
    if info is None:
        raise InputError(f"unknown model {name!r}; expected one of {', '.join(REGISTRY)}")
    if "ablation" not in info.arguments and ablation not in (None, "", "none"):
        raise InputError(f"ablations apply to HCMT only, got ablation={ablation!r} for model {name!r}")
    given = dict(
        ablation=ablation,
        levels=levels,
        L_C=L_C,
        hidden=hidden,
        heads=heads,
        clip=clip,
        blocks=blocks,
        lpe_k=lpe_k,
        attention=attention,
        ffn_bias=ffn_bias,
    )
    return info.builder(node_in, mesh_in, contact_in, out, **{k: given[k] for k in info.arguments})


def make_model(args: dict) -> Simulator:
    """A model from its saved constructor arguments (``run.yaml``'s ``model``, a checkpoint's ``model_args``)."""
    args = architecture(args)  # older runs hold other models' settings and L_H (null or 2λ + 1)
    return build_model(
        args.pop("name"), args.pop("node_in"), args.pop("mesh_in"), args.pop("contact_in"), args.pop("out"), **args
    )


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


__all__ = [
    "ABLATIONS",
    "ATTENTION_MODES",
    "GT",
    "HCMT",
    "MGN",
    "MODELS",
    "REGISTRY",
    "ModelInfo",
    "Normalizer",
    "Simulator",
    "architecture",
    "build_model",
    "checkpoint_state",
    "from_checkpoint",
    "make_model",
    "resolve_device",
    "uses_hierarchy",
]
