"""A dataset's model: the paper's Tables 8-9 for a dataset (:func:`dataset_spec`), a run's constructor arguments
(:func:`model_args`) and a model built to a dataset's widths and depths (:func:`build_for_dataset`).

It stands alone from :mod:`hcmt.domains.adapters` because it is where a dataset's adapter meets the model registry
and the built-in configs: the adapters themselves (inputs, outputs, boundary conditions) need neither.
"""

from __future__ import annotations

from hcmt.config import DATASET_NAMES, Config, load_config
from hcmt.domains.adapters import config_adapter, get_adapter
from hcmt.errors import InputError
from hcmt.models import REGISTRY, Simulator, build_model


def model_args(cfg: Config, model_name: str, meta: dict) -> dict:
    """Constructor arguments of the model (saved in ``run.yaml``): its widths, from the config and the dataset's
    dimensions (meta.json), and its own settings (:data:`hcmt.models.REGISTRY`), from ``model:``."""
    adapter = config_adapter(cfg)
    widths = adapter.widths(int(meta["dimension"]), int(meta["features"]["mesh_pos"]["shape"][-1]))
    if cfg.model.ablation and "ablation" not in REGISTRY[model_name].settings:
        raise InputError(f"model.ablation {cfg.model.ablation}: an ablation of HCMT; model {model_name} has none")
    if not cfg.data.remesh and not REGISTRY[model_name].needs_hierarchy:
        raise InputError(
            f"data.remesh false: it changes the coarse levels of HCMT's hierarchy; model {model_name} "
            "has no hierarchy (leave data.remesh at true)"
        )
    return {"name": model_name, **widths, **{k: getattr(cfg.model, k) for k in REGISTRY[model_name].settings}}


def dataset_spec(name: str) -> dict:
    """Table 8 and 9 of one dataset, read from their one home: the depths, noise, contact radius and steps from
    the dataset's config (``configs/<dataset>.yaml``), the widths and integration order from its adapter:
    ``L_C, L_H, levels, noise_std, radius, training_steps, dim, mesh_dim, integration, node_in, mesh_in,
    contact_in, out``. Node type is a one-hot of width 9 (MeshGraphNets' enum + SYMMETRIC); mesh edges carry
    ``u_ij, |u_ij|, x_ij, |x_ij|``, contact edges ``x_iq, |x_iq|``; ``integration`` 1 velocity, 2 acceleration."""
    key = name.replace("-", "_").lower()
    if key not in DATASET_NAMES:
        raise InputError(f"unknown dataset {name!r}; expected one of {', '.join(DATASET_NAMES)}")
    cfg, adapter = load_config(key), get_adapter(key)
    m, t = cfg.model, cfg.train
    return dict(
        L_C=m.L_C,
        levels=m.levels,
        L_H=2 * m.levels + 1,
        noise_std=t.noise_std,
        radius=t.contact_radius,
        training_steps=t.steps,
        dim=adapter.dim,
        mesh_dim=adapter.mesh_dim,
        integration=adapter.order,
        **adapter.widths(),
    )


def build_for_dataset(name: str, dataset: str, **overrides) -> Simulator:
    """:func:`hcmt.models.build_model` with the dataset's widths (Table 9) and depths (Table 8); keywords override
    them."""
    spec = dataset_spec(dataset)
    info = REGISTRY.get(name.lower())
    depths = {"levels", "L_C"} <= set(info.settings) if info else False  # a model with HCMT's depth settings
    kwargs = dict(levels=spec["levels"], L_C=spec["L_C"]) if depths else {}
    kwargs.update(overrides)
    return build_model(name, spec["node_in"], spec["mesh_in"], spec["contact_in"], spec["out"], **kwargs)
