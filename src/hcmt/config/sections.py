"""The config's schema: one frozen dataclass per section (``model:``, ``train:``, ``data:``), its fields' defaults
the defaults (build_model's and HCMT's too), their allowed values (:mod:`hcmt.config.choices`) and bounds the
validation (:mod:`hcmt.config.schema`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

from hcmt.config.choices import (
    ABLATION_ALIASES,
    ABLATIONS,
    ATTENTION_MODES,
    COMPILE_MODES,
    CONTACT_PAIR_NAMES,
    LOSS_DENOMINATORS,
    NOISE_NODES,
    NORMALIZER_WARMUPS,
    POLICY_NAMES,
    PRECISIONS,
    STRESS_FIELDS,
    TARGET_NAMES,
)


# Kept hand-written (stdlib dataclasses) rather than OmegaConf structured configs or pydantic models: either adds to
# the parsers' import before torch loads (docs/architecture.md, "Dependencies") for the same checks and messages.
def _field(default, *allowed, required: bool = False, minimum=None, maximum=None, above=None, says=None):
    """A schema field: ``allowed`` values, ``required`` to train, and bounds (``minimum <= v <= maximum``,
    ``v > above``) that :func:`check_schema` enforces; ``says``: how its message names the bounds."""
    return field(
        default=default,
        metadata={
            "allowed": allowed,
            "required": required,
            "minimum": minimum,
            "maximum": maximum,
            "above": above,
            "says": says,
        },
    )


@dataclass(frozen=True)
class ModelConfig:
    """``model:`` (paper Table 8 depths; ``hidden`` is the latent width)."""

    hidden: int = _field(128, minimum=1)
    heads: int = _field(4, minimum=1)
    L_C: int = _field(2, minimum=0)  # contact-mesh transformer blocks
    levels: int = _field(0, minimum=0)  # λ, the hierarchy's levels (HCMT); its L_H = 2λ + 1 blocks are derived
    clip: float = 2.0  # attention logit clip
    blocks: int = _field(15, minimum=1)  # message-passing blocks of MGN and GT
    ffn_bias: bool = True
    attention: str = _field("paper", *ATTENTION_MODES)
    target: Optional[str] = _field(None, *TARGET_NAMES)  # None: the dataset's Table 9 output
    deformation: bool = False  # hcmt's edge deformation features x_ij − u_ij and stretch
    # HCMT's ablations (paper Tables 3, 10-12; --ablation); no-remesh is read as data.remesh=false (NO_REMESH)
    ablation: Optional[str] = _field(None, *ABLATIONS, *ABLATION_ALIASES)


@dataclass(frozen=True)
class TrainConfig:
    """``train:`` (Table 8's schedule and noise; hcmt's speed and formulation options)."""

    steps: Optional[int] = _field(None, required=True, minimum=1)
    lr: Optional[float] = _field(None, required=True, above=0)
    contact_radius: Optional[float] = _field(None, required=True)  # the contact search radius (Table 8's γ)
    batch_size: int = _field(1, minimum=1)
    lr_final: Optional[float] = None  # None: constant ``lr``
    lr_decay_rate: float = 0.1  # with lr_decay_steps
    noise_std: float = _field(0.0, minimum=0)
    noise_gamma: Optional[float] = None  # None: 1.0 for a velocity target, 0.1 for acceleration
    noise_nodes: str = _field("normal", *NOISE_NODES)
    pushforward: float = _field(0.0, minimum=0, maximum=1, says="a probability in [0, 1]")
    pushforward_start: int = 0
    # the loss weight of a frame where nothing touches (no contact pair within quantities.CONTACT_TOL: the impactor
    # after it has left, where stress that stays lives); 1: the plain mean over frames. Measured: docs/RESULTS.md,
    # "The stress that stays: measured ablations"
    contact_free_weight: float = _field(1.0, minimum=0)
    normalizer_steps: int = _field(0, minimum=0)
    # the loop's conventions: hcmt's or the authors' code's (hcmt.training.policy); each key below, left null, is
    # the policy's value
    policy: str = _field("hcmt", *POLICY_NAMES)
    normalizer_warmup: Optional[str] = _field(None, *NORMALIZER_WARMUPS)
    mesh_edges_twice: Optional[bool] = None
    loss_denominator: Optional[str] = _field(None, *LOSS_DENOMINATORS)
    adam_epsilon: Optional[float] = _field(None, above=0)
    adam_epsilon_hat: Optional[bool] = None
    lr_decay_steps: Optional[int] = _field(None, minimum=1)  # lr·rate^(step/this), no floor; hcmt: lr->lr_final
    log_every: int = _field(100, minimum=1)
    checkpoint_every: int = _field(1000, minimum=1)
    # also keep the checkpoint of every keep_every-th step as step_<N>.pt (0: none), so that a long run's checkpoint
    # can be chosen afterwards on more than best.pt's position RMSE (peak, deflection, ghost)
    keep_every: int = _field(0, minimum=0)
    valid_every: int = _field(0, minimum=0)
    valid_trajectories: int = _field(2, minimum=0)
    contact_pairs: str = _field("all", *CONTACT_PAIR_NAMES)
    workers: int = _field(0, minimum=0)
    checkpoint_blocks: bool = False
    precision: str = _field("fp32", *PRECISIONS)
    compile: str = _field("auto", *COMPILE_MODES)
    deterministic: bool = False


@dataclass(frozen=True)
class DataConfig:
    """``data:``."""

    exclude_trajectories: Optional[tuple] = None  # trajectory indices of the train split to leave out
    stress_field: str = _field("stress", *STRESS_FIELDS)  # stress_max: `generate --peak-stress`
    # hold the training split in memory instead of reading each item's frames from the file: a step of the shipped
    # recipe took 145 against 160 ms of CPU on the `small` preset; memory grows with the split (docs/RESULTS.md)
    in_memory: bool = False
    # the coarse levels' edges of HCMT's hierarchy: Delaunay remeshing of the pooled nodes (the paper), or, false,
    # the kept nodes two hops apart on the finer level (BSMS; the paper's "HCMT without remeshing" ablation, appendix
    # "Additional Ablation Study"); hcmt.graph.hierarchy.build_hierarchy. Old spelling: model.ablation=no-remesh
    remesh: bool = True


SECTIONS = {"model": ModelConfig, "train": TrainConfig, "data": DataConfig}
