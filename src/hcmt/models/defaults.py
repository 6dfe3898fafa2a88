"""Per-dataset settings of the paper, read from their one home: Table 8 (depths L_C, λ, noise, contact radius γ,
training steps) from the dataset's config (``configs/<dataset>.yaml``), Table 9 (inputs, outputs, widths, integration
order) from its adapter (:mod:`hcmt.train.adapters`).

Feature widths follow Table 9: node type is a one-hot of width 9 (MeshGraphNets' enum + SYMMETRIC); mesh edges
carry ``u_ij, |u_ij|`` in mesh space and ``x_ij, |x_ij|`` in world space (``mesh_dim + 1 + dim + 1``); contact
edges ``x_iq, |x_iq|`` (``dim + 1``). ``integration`` is the updater's order (1: velocity, 2: acceleration).
"""
from __future__ import annotations

DATASET_NAMES = ("impact_plate", "deforming_plate", "sphere_simple", "deformable_plate")


def dataset_spec(name: str) -> dict:
    """Table 8 and 9 of one dataset: ``L_C, L_H, levels, noise_std, radius, training_steps, dim, mesh_dim,
    integration, node_in, mesh_in, contact_in, out``."""
    from hcmt.train.adapters import get_adapter
    from hcmt.train.config import load_config

    key = name.replace("-", "_").lower()
    if key not in DATASET_NAMES:
        raise ValueError(f"unknown dataset {name!r}; expected one of {', '.join(DATASET_NAMES)}")
    cfg, adapter = load_config(key), get_adapter(key)
    m, t = cfg["model"], cfg["train"]
    return dict(L_C=m["L_C"], levels=m["levels"], L_H=2 * m["levels"] + 1, noise_std=t["noise_std"],
                radius=t["contact_radius"], training_steps=t["steps"], dim=adapter.dim, mesh_dim=adapter.mesh_dim,
                integration=adapter.order, **adapter.widths())
