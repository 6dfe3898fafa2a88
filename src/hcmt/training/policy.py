"""The training loop's conventions, chosen by one key, ``train.policy``: ``hcmt`` (the MeshGraphNets conventions,
hcmt's default and its recommendation for its own studies) or ``official`` (the authors' TF2 code,
github.com/yuyudeep/hcmt, for a faithful reproduction of their runs). Each of the policy's fields is also a
``train.*`` key; left unset (null), it is the policy's value.

===================  ==========  ===========  ==================================================================
field                hcmt        official     the authors' code
===================  ==========  ===========  ==================================================================
normalizer_warmup    all         nodes        run_model.py: the first steps call only _build_graph (the node
                                              normalizer); edge and output normalizers start with training
mesh_edges_twice     false       true         core_model.py: level 0's mesh edges enter the edge normalizer twice
loss_denominator     masked      nodes        model.py: reduce_mean over all N nodes of the masked squared error
adam_epsilon         1e-8        1e-7         tf.keras.optimizers.Adam's default ...
adam_epsilon_hat     false       true         ... in Keras' "epsilon hat" form (:func:`keras_epsilon`)
lr_decay_steps       null        1e6          exponential_decay(lr, step, decay_steps=1e6, decay_rate=0.1), no floor
===================  ==========  ===========  ==================================================================

(``lr_decay_steps`` null: the decay runs from ``lr`` to ``lr_final`` over the run, :func:`learning_rate`.)
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

import torch

from hcmt.config import TrainConfig
from hcmt.training.schedule import keras_epsilon, learning_rate


@dataclass(frozen=True)
class TrainingPolicy:
    """How the loop warms up its normalizers, divides its loss and parameterizes Adam and the decay."""

    normalizer_warmup: str = "all"  # all | nodes: which normalizers accumulate during the warm-up steps
    mesh_edges_twice: bool = False
    loss_denominator: str = "masked"  # masked | nodes
    adam_epsilon: float = 1e-8
    adam_epsilon_hat: bool = False
    lr_decay_steps: int | None = None

    def accumulate(self, model, graph, warmup: bool, frozen: bool) -> bool:
        """Whether this step's forward accumulates normalizer statistics, after what the policy accumulates
        before it: during a ``nodes`` warm-up the node normalizer alone, with ``mesh_edges_twice`` level 0's mesh
        edges once more (the forward adds them a second time)."""
        if frozen:
            return False
        if warmup and self.normalizer_warmup == "nodes":
            model.node_normalizer.accumulate(graph.node_features, graph.node_mask)
            return False
        if self.mesh_edges_twice and graph.level_edges:
            model.mesh_normalizer.accumulate(graph.mesh_features, graph.mesh_mask)
        return True

    def loss_count(self, graph, mask: torch.Tensor) -> torch.Tensor:
        """The loss's denominator: ``masked`` the unmasked entries (a mean over what is predicted), ``nodes`` the
        N (real) nodes, the masked error summed over channels."""
        if self.loss_denominator == "nodes":
            n = graph.node_mask.sum() if graph.node_mask is not None else torch.tensor(float(graph.num_nodes))
            return n.to(mask.device, torch.float32).clamp_min(1.0)
        return (mask != 0).sum().to(torch.float32).clamp_min(1.0)  # entries, not weights (contact_free_weight)

    def epsilon(self, t: int, beta2: float) -> float:
        """PyTorch Adam's ε at optimizer step ``t`` (1-based): ``adam_epsilon``, or with ``adam_epsilon_hat`` the ε
        that makes it Keras' update with ε̂ = ``adam_epsilon``."""
        return keras_epsilon(self.adam_epsilon, beta2, t) if self.adam_epsilon_hat else self.adam_epsilon

    def learning_rate(self, step: int, tc: TrainConfig) -> float:
        return learning_rate(step, tc.steps, tc.lr, tc.lr_final or tc.lr, self.lr_decay_steps, tc.lr_decay_rate)


#: the named policies (``train.policy``)
POLICIES = {
    "hcmt": TrainingPolicy(),
    "official": TrainingPolicy(
        normalizer_warmup="nodes",
        mesh_edges_twice=True,
        loss_denominator="nodes",
        adam_epsilon=1e-7,
        adam_epsilon_hat=True,
        lr_decay_steps=1_000_000,
    ),
}


def policy_of(tc: TrainConfig) -> TrainingPolicy:
    """``train.policy``'s :class:`TrainingPolicy`, with the fields a config sets (non-null) in its place."""
    return replace(
        POLICIES[tc.policy],
        **{f.name: getattr(tc, f.name) for f in fields(TrainingPolicy) if getattr(tc, f.name) is not None},
    )
