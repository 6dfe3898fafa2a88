"""The values a config key or a command option may take, declared once: the config's schema
(:mod:`hcmt.config.sections`), the command's parsers and the modules that act on each value read these tuples, so a
value added here and not handled there (or the reverse) fails ``tests/training/test_config_choices.py``. Light (no
torch): the command's parsers read them before torch loads, and every layer above may import them."""

from __future__ import annotations

#: the datasets hcmt knows (a config's ``dataset``; each has an adapter in :mod:`hcmt.domains.adapters`)
DATASET_NAMES = ("impact_plate", "deforming_plate", "sphere_simple", "deformable_plate")
#: ``torch.compile`` modes (``train.compile``, ``--compile``); ``none`` is eager, ``auto`` compiles a long run where
#: a compiler exists (:func:`hcmt.models.base.resolve_compile`); the rest are ``torch.compile``'s own modes
COMPILE_MODES = ("none", "auto", "default", "reduce-overhead", "max-autotune")
TORCH_COMPILE_MODES = COMPILE_MODES[2:]
#: inference's modes (``--compile`` of ``hcmt rollout / evaluate / predict / sweep``) add ``aot``: the forward exported
#: ahead of time with symbolic sizes and compiled once per machine (:mod:`hcmt.models.export`), loaded in milliseconds
INFERENCE_COMPILE_MODES = (*COMPILE_MODES, "aot")
#: the models (:data:`hcmt.models.REGISTRY`, in this order) and HCMT's ablations (paper Tables 3, 10-12)
MODELS = ("hcmt", "mgn", "gt")
ABLATIONS = ("late-contact", "only-cmt", "only-hmt", "lpe", "single-branch")
#: the paper's remeshing ablation ("HCMT without remeshing", appendix "Additional Ablation Study") changes the graph,
#: not the model: it is ``data.remesh: false``. Its old spelling, ``model.ablation: no-remesh`` (configs, ``--set``,
#: ``hcmt train --ablation no-remesh``, the ``model`` of run.yaml files and checkpoints written before), still reads,
#: as an alias: :class:`Config` and :func:`current_model_args` translate it where a config or model arguments are read
NO_REMESH = "no-remesh"
ABLATION_ALIASES = (NO_REMESH,)
#: ``init_normalizers``: a fine-tuned run keeps its source's normalizer statistics, frozen (the few runs of a new
#: family make poor statistics), or zeroes them and accumulates them afresh on its own data
INIT_NORMALIZERS = ("keep", "reaccumulate")
#: the bounds of the counts every command and API function takes (one rule: above the bound, refused in one line):
#: trajectories of one split, designs of one design check or sweep, trajectories or designs in one batch
MAX_TRAJECTORIES, MAX_DESIGNS, MAX_BATCH = 100_000, 10_000, 1024
#: ``model.attention`` (:mod:`hcmt.models.attention`, whose ``MODES`` this is): ``paper``, eq. 1's per-receiver
#: softmax with the edge term after the clip; ``official``, the authors' unnormalized sum
ATTENTION_MODES = ("paper", "official")
#: ``model.target``: the kinematic quantity the model predicts (:data:`hcmt.domains.adapters.TARGETS`, keyed by these:
#: each one's update order and noise correction)
TARGET_NAMES = ("velocity", "acceleration")
#: ``train.noise_nodes``: which nodes get training noise (:func:`hcmt.domains.adapters.noise_mask`)
NOISE_NODES = ("normal", "predicted")
#: ``train.contact_pairs``: which node types may form contact edges (:data:`hcmt.domains.adapters.CONTACT_PAIRS`)
CONTACT_PAIR_NAMES = ("all", "official")
#: ``train.policy``: the training loop's conventions (:data:`hcmt.training.policy.POLICIES`), and the values of two of
#: the keys a config may set in their place (:class:`hcmt.training.policy.TrainingPolicy`)
POLICY_NAMES = ("hcmt", "official")
NORMALIZER_WARMUPS = ("all", "nodes")
LOSS_DENOMINATORS = ("masked", "nodes")
#: ``train.precision``: the forward and loss in float32 or under bfloat16 autocast (:mod:`hcmt.training.trainer`)
PRECISIONS = ("fp32", "bf16")
#: ``data.stress_field``, ``--stress-field``: the recorded stress, or ``stress_max`` (``hcmt generate --peak-stress``)
STRESS_FIELDS = ("stress", "stress_max")
