"""Dataset adapters: the paper's Table 9 (inputs and outputs of each dataset) and each dataset's boundary
conditions, applied the same way in the training loss and in rollout.

========================  =====================================================  ==================  ============
dataset                   node inputs f_i                                        outputs o_i         updater
========================  =====================================================  ==================  ============
impact_plate              node type, velocity x^t − x^{t−1}, density ρ, modulus Y  velocity, stress    1st order
deforming_plate           node type (+ the obstacle's prescribed velocity)        velocity, stress    1st order
sphere_simple             node type, velocity                                     acceleration        2nd order
deformable_plate          node type, Poisson ratio ν                              velocity            1st order
========================  =====================================================  ==================  ============

Boundary conditions: HANDLE nodes follow the data (fixed); SYMMETRIC nodes keep the data's x (the symmetry line);
``prescribed`` node types (the pusher in Deforming Plate, the collider in Deformable Plate) move as the data says.
Those entries are masked out of the loss and overwritten in rollout. Stress is predicted at every node.

Choices where the paper is silent: Deforming Plate's obstacle velocity input follows MeshGraphNets (the obstacle's
next-step displacement, zero elsewhere); Deformable Plate's collider is prescribed as in GGNS, and per Table 9 gets no
velocity input; inputs of the Impact Plate's density and modulus are taken per node from the dataset.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import torch
from torch import Tensor

from hcmt.config import NOISE_NODES, Config
from hcmt.data.format import NODE_TYPE_SIZE, NodeType
from hcmt.domains.updater import update_positions
from hcmt.errors import InputError
from hcmt.graph.contact import OFFICIAL_IMPACT_PLATE_TYPES


@dataclass(frozen=True, kw_only=True)
class Adapter:
    """One dataset's row of Table 9 and its boundary conditions; built with keywords (:data:`ADAPTERS`)."""

    name: str
    dim: int  # world dimension d
    mesh_dim: int  # mesh-space dimension (2 for cloth in 3-D)
    node_fields: tuple[str, ...]  # static per-node fields appended to the node features
    velocity_input: bool  # x^t − x^{t−1} among the inputs
    obstacle_velocity_input: bool  # prescribed nodes' next displacement among the inputs (MGN deforming plate)
    stress_output: bool
    order: int  # 1: predict velocity (x^{t+1} = x^t + v); 2: predict acceleration (x^{t+1} = 2x^t − x^{t−1} + a)
    prescribed: tuple[int, ...]  # node types whose positions come from the data
    self_contact: bool
    contact_types: tuple[tuple[int, int], ...] | None  # allowed (type, type) contact pairs; None: any two objects
    deformation: bool = False  # model.deformation: edge deformation x_ij − u_ij among the edge features
    stress_field: str = "stress"  # data.stress_field: the dataset field the stress output learns and is judged on

    @property
    def history(self) -> int:
        """Frames needed before the first prediction (x^{t−1})."""
        return 1 if (self.velocity_input or self.order == 2) else 0

    def node_in(self, dim: int) -> int:
        return NODE_TYPE_SIZE + dim * (self.velocity_input + self.obstacle_velocity_input) + len(self.node_fields)

    def out(self, dim: int) -> int:
        return dim + int(self.stress_output)

    def widths(self, dim: int | None = None, mesh_dim: int | None = None) -> dict[str, int]:
        """The model's input/output widths (Table 9), computed here once: node inputs, mesh-edge features
        ``u_ij, |u_ij|, x_ij, |x_ij|`` (``mesh_dim + 1 + dim + 1``), contact features ``x_iq, |x_iq|`` and outputs.
        ``dim``/``mesh_dim`` default to the dataset's; a dataset's meta.json may give them."""
        d, m = dim or self.dim, mesh_dim or self.mesh_dim
        mesh_in = m + 1 + d + 1 + (d + 1 if self.deformation else 0)
        return {"node_in": self.node_in(d), "mesh_in": mesh_in, "contact_in": d + 1, "out": self.out(d)}


def _pairs(*names: tuple[str, str]) -> tuple[tuple[int, int], ...]:
    return tuple((int(NodeType[a]), int(NodeType[b])) for a, b in names)


ADAPTERS = {
    a.name: a
    for a in (
        Adapter(
            name="impact_plate",
            dim=2,
            mesh_dim=2,
            node_fields=("density", "modulus"),
            velocity_input=True,
            obstacle_velocity_input=False,
            stress_output=True,
            order=1,
            prescribed=(),
            self_contact=False,
            # ball <-> plate between different objects. The official code links OBSTACLE -> NORMAL only; here
            # SYMMETRIC nodes (on both bodies' symmetry line) take part too, so the contact at x = 0 -- where the
            # ball first touches -- is seen (hcmt's choice)
            contact_types=_pairs(
                ("OBSTACLE", "NORMAL"), ("OBSTACLE", "SYMMETRIC"), ("SYMMETRIC", "NORMAL"), ("SYMMETRIC", "SYMMETRIC")
            ),
        ),
        Adapter(
            name="deforming_plate",
            dim=3,
            mesh_dim=3,
            node_fields=(),
            velocity_input=False,
            obstacle_velocity_input=True,
            stress_output=True,
            order=1,
            prescribed=(int(NodeType.OBSTACLE),),
            self_contact=False,
            contact_types=None,
        ),
        Adapter(
            name="sphere_simple",
            dim=3,
            mesh_dim=2,
            node_fields=(),
            velocity_input=True,
            obstacle_velocity_input=False,
            stress_output=False,
            order=2,
            prescribed=(),
            self_contact=True,
            contact_types=None,
        ),
        Adapter(
            name="deformable_plate",
            dim=2,
            mesh_dim=2,
            node_fields=("poisson_ratio",),
            velocity_input=False,
            obstacle_velocity_input=False,
            stress_output=False,
            order=1,
            prescribed=(int(NodeType.OBSTACLE),),
            self_contact=False,
            contact_types=None,
        ),
    )
}


# ``train.contact_pairs``: which node types may form contact edges, for every model alike.
#   all:      the adapter's own rule (Impact Plate: NORMAL, OBSTACLE and SYMMETRIC nodes of different bodies)
#   official: OBSTACLE <-> NORMAL only, as the authors' code builds them (yuyudeep/hcmt model.py, contact_node_2D)
CONTACT_PAIRS = {"all": None, "official": OFFICIAL_IMPACT_PLATE_TYPES}


def get_adapter(name: str, contact_pairs: str = "all") -> Adapter:
    """The dataset's adapter; ``contact_pairs="official"`` restricts contacts to OBSTACLE <-> NORMAL nodes."""
    if name not in ADAPTERS:
        raise InputError(f"unknown dataset adapter {name!r}; expected one of {', '.join(ADAPTERS)}")
    if contact_pairs not in CONTACT_PAIRS:
        raise InputError(
            f"train.contact_pairs: unknown value {contact_pairs!r}; expected one of {', '.join(CONTACT_PAIRS)}"
        )
    adapter = ADAPTERS[name]
    if CONTACT_PAIRS[contact_pairs] is not None:
        adapter = replace(adapter, contact_types=CONTACT_PAIRS[contact_pairs])
    return adapter


#: ``model.target``: the kinematic quantity the model predicts, and its updater's order.
#:   velocity:     x^{t+1} − x^t, first-order update (the paper's Table 9 for Impact Plate / Deforming Plate)
#:   acceleration: x^{t+1} − 2x^t + x^{t−1}, second-order update (MeshGraphNets' cloth, Sphere Simple's Table 9)
TARGETS = {"velocity": 1, "acceleration": 2}
#: the noise correction γ of each target when ``train.noise_gamma`` is not set: 1 for velocity (GNS /
#: MeshGraphNets' plates: the next step undoes the whole noise), 0.1 for acceleration (MeshGraphNets' cloth)
DEFAULT_GAMMA = {"velocity": 1.0, "acceleration": 0.1}
#: ``train.noise_nodes``: which nodes get training noise.
#:   normal:    NORMAL nodes only (MeshGraphNets and the authors' HCMT code)
#:   predicted: every position channel the model predicts (the ball's OBSTACLE nodes too; the symmetry line's y)
#: (the names: :data:`hcmt.config.NOISE_NODES`, imported above)


def config_adapter(cfg: Config) -> Adapter:
    """The adapter a config asks for: ``dataset``, ``train.contact_pairs``, ``model.target`` (None: the
    dataset's own, Table 9), ``model.deformation`` and ``data.stress_field``."""
    mc = cfg.model
    adapter = replace(get_adapter(cfg.dataset, cfg.train.contact_pairs), stress_field=cfg.data.stress_field)
    if mc.deformation:
        if adapter.mesh_dim != adapter.dim:
            raise InputError(
                f"model.deformation: {adapter.name} has a {adapter.mesh_dim}-D mesh space in a "
                f"{adapter.dim}-D world; edge deformation needs both of one dimension"
            )
        adapter = replace(adapter, deformation=True)
    if mc.target is None:
        return adapter
    return replace(adapter, order=TARGETS[mc.target])


def target_name(adapter: Adapter) -> str:
    return "velocity" if adapter.order == 1 else "acceleration"


def noise_gamma(cfg: Config, adapter: Adapter) -> float:
    """γ of ``train.noise_gamma``, or the target's default (:data:`DEFAULT_GAMMA`)."""
    gamma = cfg.train.noise_gamma
    return DEFAULT_GAMMA[target_name(adapter)] if gamma is None else gamma


def position_mask(adapter: Adapter, node_type: Tensor, dim: int) -> Tensor:
    """[N, dim] float: 1 where the position channel is predicted, 0 where a boundary condition sets it."""
    nt = node_type.reshape(-1)
    mask = torch.ones(nt.shape[0], dim, dtype=torch.float32, device=nt.device)
    fixed = torch.tensor((int(NodeType.HANDLE), *adapter.prescribed), dtype=nt.dtype, device=nt.device)
    mask[torch.isin(nt, fixed)] = 0.0
    mask[nt == int(NodeType.SYMMETRIC), 0] = 0.0  # symmetry line: x is fixed
    mask[nt == int(NodeType.WALL_BOUNDARY), dim - 1] = 0.0  # a roller (Impact Plate's support ring): y is fixed
    return mask


def output_mask(adapter: Adapter, node_type: Tensor, dim: int) -> Tensor:
    """[N, out] loss mask: the position mask, plus a stress channel predicted everywhere."""
    mask = position_mask(adapter, node_type, dim)
    if adapter.stress_output:
        mask = torch.cat([mask, torch.ones_like(mask[:, :1])], dim=1)
    return mask


def node_features(
    adapter: Adapter, static: dict[str, Tensor], pos: Tensor, prev: Tensor | None, next_prescribed: Tensor | None
) -> Tensor:
    """Raw node inputs f_i [N, node_in] (Table 9)."""
    nt = static["node_type"].reshape(-1)
    parts = [torch.nn.functional.one_hot(nt.long(), NODE_TYPE_SIZE).to(pos.dtype)]
    if adapter.velocity_input:
        parts.append(pos - prev)
    if adapter.obstacle_velocity_input:
        moving = torch.isin(nt, torch.tensor(adapter.prescribed, dtype=nt.dtype, device=nt.device))
        parts.append(torch.where(moving[:, None], next_prescribed - pos, torch.zeros_like(pos)))
    for name in adapter.node_fields:
        parts.append(static[name].reshape(nt.shape[0], -1).to(pos.dtype))
    return torch.cat(parts, dim=1)


def target(adapter: Adapter, pos: Tensor, prev: Tensor, nxt: Tensor, stress_next: Tensor | None) -> Tensor:
    """Physical-unit target [N, out]: velocity x^{t+1} − x^t or acceleration x^{t+1} − 2x^t + x^{t−1}, then stress."""
    kin = nxt - pos if adapter.order == 1 else nxt - 2 * pos + prev
    if adapter.stress_output:
        return torch.cat([kin, stress_next.reshape(pos.shape[0], 1)], dim=1)
    return kin


def integrate(
    adapter: Adapter, output: Tensor, pos: Tensor, prev: Tensor, true_next: Tensor, node_type: Tensor
) -> tuple[Tensor, Tensor | None]:
    """The updater plus boundary conditions: physical output -> (x^{t+1}, σ^{t+1} or None).

    Positions set by boundary conditions are copied from ``true_next`` (the data's next frame)."""
    nxt, rest = update_positions(output, pos, prev, order=adapter.order)
    keep = position_mask(adapter, node_type, pos.shape[1]).bool()
    nxt = torch.where(keep, nxt, true_next)
    return nxt, (rest[:, :1] if adapter.stress_output else None)


def noise_mask(adapter: Adapter, node_type: Tensor, dim: int, nodes: str = "normal") -> Tensor:
    """[N, dim] float: where training noise goes (``train.noise_nodes``, :data:`NOISE_NODES`): NORMAL nodes only
    (MeshGraphNets / the official HCMT code), or every predicted position channel (:func:`position_mask`)."""
    if nodes == "predicted":
        return position_mask(adapter, node_type, dim)
    if nodes != "normal":
        raise InputError(f"train.noise_nodes: unknown value {nodes!r}; expected one of {', '.join(NOISE_NODES)}")
    normal = (node_type.reshape(-1) == int(NodeType.NORMAL)).float()[:, None]
    return normal.expand(-1, dim)


def exclude_trajectories(names: list[str], excluded: list[int] | None) -> np.ndarray:
    """Indices of the trajectories to use, dropping the listed ones (e.g. Deforming Plate's 173 and 233)."""
    excluded = [int(i) for i in excluded or []]
    bad = [i for i in excluded if not 0 <= i < len(names)]
    if bad:
        raise InputError(
            f"data.exclude_trajectories {bad}: out of range for a split of {len(names)} trajectories "
            "(the deforming_plate configs leave out the public data's bad trajectories 173 and 233; "
            "for other data set data.exclude_trajectories=[])"
        )
    keep = np.ones(len(names), bool)
    keep[excluded] = False
    return np.flatnonzero(keep)
