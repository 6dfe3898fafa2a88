"""Parts shared by HCMT, MGN and GT: input/target normalizers, encoders, decoder (paper "Features and Encoder
Layer", "Decoder and Updater"; MeshGraphNets' encode-process-decode).

* encoders ε_node, ε_mesh, ε_contact: MLPs with LayerNorm (:func:`hcmt.models.mlp.mlp`); ε_mesh is **one** encoder
  for every level (the paper: it "shares weight parameters across levels"), and so is its normalizer;
* decoder: MLP without LayerNorm, producing the **normalized** output;
* normalizers (:class:`~hcmt.models.normalizer.Normalizer`) for node, mesh-edge and contact-edge inputs and for the
  targets. They accumulate when ``accumulate`` is true; ``accumulate=None`` means "while ``self.training``".
"""

from __future__ import annotations

import importlib.util
import os
import shutil
from pathlib import Path

import torch
from torch import Tensor, nn
from torch.utils.checkpoint import checkpoint

from hcmt.config import TORCH_COMPILE_MODES
from hcmt.errors import DatasetError, InputError
from hcmt.graph.batch import Graph

from .mlp import mlp
from .normalizer import Normalizer


def resolve_device(device: str | None = None) -> torch.device:
    """``None``: CUDA when available, else the CPU. An unknown device, or CUDA on a CPU-only torch, is refused with
    one line (:class:`hcmt.errors.InputError` naming ``device``)."""
    if device is None:
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    try:
        dev = torch.device(device)
    except (RuntimeError, ValueError):
        raise InputError(f"{device!r}: not a device; expected cpu, cuda or cuda:N", param="device") from None
    if dev.type == "cuda":
        if not torch.cuda.is_available():
            raise InputError(
                f"{device}: this torch has no usable CUDA device (torch {torch.__version__}); use the CPU (cpu)",
                param="device",
            )
        if dev.index is not None and dev.index >= torch.cuda.device_count():
            raise InputError(f"{device}: only {torch.cuda.device_count()} CUDA device(s) here", param="device")
    elif dev.type != "cpu":
        raise InputError(f"{device}: unsupported device type {dev.type!r}; expected cpu or cuda", param="device")
    return dev


def compile_simulator(model: nn.Module, mode: str, dynamic: bool = False) -> nn.Module:
    """``torch.compile`` of a model. ``dynamic=False``: for padded graphs (:func:`hcmt.graph.batch.pad_graph`),
    static shapes, one compiled graph per bucketed shape (training; CUDA graphs); Dynamo's recompile limit (8 by
    default, after which it silently runs eager) is raised to hold the few dozen buckets a run meets.
    ``dynamic=True``: symbolic sizes, one compiled graph for every mesh (rollouts of other designs reuse it: no
    padding, no recompilation; on one CPU thread as fast as the static padded graph, docs/RESULTS.md). On several
    CPU threads, mode ``default`` keeps Inductor's fused kernels on one (no atomic adds) and the matmuls on all."""
    if mode not in TORCH_COMPILE_MODES:
        raise InputError(f"compile mode {mode!r}: expected one of {', '.join(TORCH_COMPILE_MODES)}")
    import torch._dynamo

    torch._dynamo.config.recompile_limit = max(torch._dynamo.config.recompile_limit, 64)
    options = None
    if mode == "default" and torch.get_num_threads() > 1 and all(p.device.type == "cpu" for p in model.parameters()):
        # Inductor's own kernels on one thread, the matmuls on all: on several it writes every scatter-add (the
        # backward of each gather) with atomic adds, and compiled training ran no faster on 2 threads than on one
        # (impact_plate_cpu: 11.95 against 11.67 samples/s; 16.01 on 2 threads this way, docs/RESULTS.md)
        options = {"cpp.threads": 1}
    return torch.compile(model, mode=None if mode == "default" else mode, dynamic=dynamic, options=options)


#: ``auto`` compiles a training run of at least this many steps: the first compilation of a shape costs about 5
#: minutes of one CPU core (later runs read the persistent cache), and a compiled step saves 40-70 ms of CPU
#: (69.5 against 112-151 ms, the shipped recipe at 1 thread), so it pays back after about 5,000 steps
AUTO_COMPILE_STEPS = 5000
#: ``auto`` compiles rollouts (a design check, an evaluation) of at least this many model steps in all: one
#: compilation with symbolic sizes serves every design; it costs 25 s of one CPU core with a warm persistent cache
#: (about 65 s the first time on a machine), and a compiled step of the shipped model saves about 20 ms (one thread:
#: 1.7 s per design against 3.5 s eager, 88 steps), so it pays back after about 1,300-3,300 steps
AUTO_COMPILE_ROLLOUT_STEPS = 2000


def resolve_compile(
    mode: str, *, steps: int, device: torch.device, lpe: bool = False, threshold: int = AUTO_COMPILE_STEPS
) -> str:
    """The ``torch.compile`` mode a run uses: ``auto`` is ``default`` for at least ``threshold`` steps
    (:data:`AUTO_COMPILE_STEPS` for training, :data:`AUTO_COMPILE_ROLLOUT_STEPS` for rollouts) where Inductor has
    its compiler (a C++ compiler on the CPU, Triton on CUDA) and the model is compilable (not the ``lpe``
    ablation), else ``none``; any other mode is itself."""
    if mode != "auto":
        return mode
    if lpe or steps < threshold:
        return "none"
    if device.type == "cuda":
        return "default" if importlib.util.find_spec("triton") is not None else "none"
    compilers = (os.environ.get("CXX"), "g++", "c++", "clang++")
    return "default" if any(c and shutil.which(c) for c in compilers) else "none"


def compile_cache_dir() -> Path:
    """Where compiled kernels and packages persist across processes and sessions (Inductor's FX-graph and
    AOT-autograd caches, the ahead-of-time packages): ``$TORCHINDUCTOR_CACHE_DIR`` when set before hcmt.models is
    imported, else ``$XDG_CACHE_HOME/hcmt/inductor`` (``~/.cache/hcmt/inductor``), not Inductor's default under the
    temporary folder, so a shape's compilation is paid once per machine."""
    if os.environ.get("TORCHINDUCTOR_CACHE_DIR"):
        return Path(os.environ["TORCHINDUCTOR_CACHE_DIR"])
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "hcmt" / "inductor"


# Inductor fixes its cache folder the first time anything asks for it, and importing torch_geometric (the models'
# scatter and softmax) asks: without this line every compiled kernel and package would land under the temporary
# folder, not in compile_cache_dir(). hcmt.models imports this module before any model; a folder set before it wins.
os.environ.setdefault("TORCHINDUCTOR_CACHE_DIR", str(compile_cache_dir()))


class Simulator(nn.Module):
    r"""Encoder, decoder and normalizers; subclasses define ``forward(graph, accumulate=None) -> [N, out]``.

    Args (every model's first four):
        node_in: width of the raw node features :math:`f_i` (Table 9: node-type one-hot 9, velocity
            :math:`x_i^t - x_i^{t-1}`, and the dataset's static fields such as ρ and Y).
        mesh_in: width of the raw mesh-edge features :math:`u_{ij}, |u_{ij}|, x_{ij}, |x_{ij}|` (+ the
            deformation :math:`x_{ij} - u_{ij}` with ``model.deformation``).
        contact_in: width of the raw contact-edge features :math:`x_{iq}, |x_{iq}|`.
        out: width of the output: the velocity (or acceleration) per dimension, plus the stress σ.
        hidden: the latent width of the encoders and decoder.

    ``checkpoint_blocks = True`` (``train.checkpoint_blocks``) recomputes each processor block's activations in
    the backward pass instead of keeping them (:func:`torch.utils.checkpoint.checkpoint`): memory for depth, the
    same gradients (tests/models/test_models_invariants.py)."""

    checkpoint_blocks: bool = False

    def run_block(self, block, *args):
        """``block(*args)``, with activation checkpointing while training when ``checkpoint_blocks`` is set."""
        if self.checkpoint_blocks and self.training and torch.is_grad_enabled():
            return checkpoint(block, *args, use_reentrant=False)
        return block(*args)

    def attention_taps(self) -> list:
        """Every :class:`~hcmt.models.attention.AttentionTap` of the model with where it sits
        (:class:`~hcmt.models.attention.TapSite`: map name, stage, block, level), in no particular order;
        :func:`~hcmt.models.attention.recording` hooks these and refuses a model with a tap it does not list.
        None by default: a model without attention (MGN)."""
        return []

    def __init__(self, node_in: int, mesh_in: int, contact_in: int, out: int, *, hidden: int = 128):
        super().__init__()
        for name, size in (
            ("node_in", node_in),
            ("mesh_in", mesh_in),
            ("contact_in", contact_in),
            ("out", out),
            ("hidden", hidden),
        ):
            if int(size) < 1:
                raise InputError(f"{name} must be a positive size, got {size}")
        self.node_in, self.mesh_in, self.contact_in, self.out, self.hidden = node_in, mesh_in, contact_in, out, hidden
        self.node_normalizer = Normalizer(node_in)
        self.mesh_normalizer = Normalizer(mesh_in)
        self.contact_normalizer = Normalizer(contact_in)
        self.output_normalizer = Normalizer(out)
        self.node_encoder = mlp(node_in, hidden, hidden)
        self.mesh_encoder = mlp(mesh_in, hidden, hidden)
        self.contact_encoder = mlp(contact_in, hidden, hidden)
        self.decoder = mlp(hidden, hidden, out, layer_norm=False)

    # -- normalization -------------------------------------------------------------------------------------------
    def _accumulating(self, accumulate: bool | None) -> bool:
        return self.training if accumulate is None else bool(accumulate)

    def normalize_target(self, target: Tensor, accumulate: bool | None = None, mask: Tensor | None = None) -> Tensor:
        """Targets in the units the loss compares with ``forward``'s output (MGN: the output normalizer); ``mask``
        the graph's ``node_mask`` of a padded graph."""
        return self.output_normalizer(target, self._accumulating(accumulate), mask)

    def denormalize(self, output: Tensor) -> Tensor:
        """``forward``'s normalized output back to physical units."""
        return self.output_normalizer.inverse(output)

    @torch.no_grad()
    def accumulate(self, graph: Graph, target: Tensor) -> None:
        """Add one training batch to every normalizer the model uses, exactly as ``forward(graph,
        accumulate=True)`` and ``normalize_target(target, accumulate=True)`` would. A compiled step calls this
        eagerly and then the compiled ``forward`` without accumulation, so the compiled graph mutates no buffer
        (CUDA graphs can replay it); padded graphs' dummy rows are left out through their masks."""
        self.node_normalizer.accumulate(graph.node_features, graph.node_mask)
        self.mesh_normalizer.accumulate(*self.mesh_inputs(graph))
        if self.contact_encoder is not None:
            self.contact_normalizer.accumulate(graph.contact_features, graph.contact_mask)
        self.output_normalizer.accumulate(target, graph.node_mask)

    def mesh_inputs(self, graph: Graph) -> tuple[Tensor, Tensor | None]:
        """The raw mesh-edge features the mesh normalizer sees in one call, and their mask (HCMT: every level's)."""
        return graph.mesh_features, graph.mesh_mask

    # -- encoders ------------------------------------------------------------------------------------------------
    def check_graph(self, graph: Graph) -> None:
        n = graph.num_nodes
        checks = (
            ("node_features", graph.node_features, self.node_in, n),
            ("mesh_features", graph.mesh_features, self.mesh_in, graph.mesh_edges.shape[-1]),
            ("contact_features", graph.contact_features, self.contact_in, graph.contact_edges.shape[-1]),
        )
        for name, x, width, rows in checks:
            if x.dim() != 2 or x.shape[1] != width or x.shape[0] != rows:
                raise DatasetError(f"expected shape [{rows}, {width}], got {tuple(x.shape)}", field=name)
        for name, e in (("mesh_edges", graph.mesh_edges), ("contact_edges", graph.contact_edges)):
            if e.dim() != 2 or e.shape[0] != 2:
                raise DatasetError(f"expected edges [2, E], got {tuple(e.shape)}", field=name)

    def encode_nodes(self, graph: Graph, accumulate: bool) -> Tensor:
        return self.node_encoder(self.node_normalizer(graph.node_features, accumulate, graph.node_mask))

    def encode_mesh(self, features: Tensor, mask: Tensor | None = None, *, accumulate: bool) -> Tensor:
        return self.mesh_encoder(self.mesh_normalizer(features, accumulate, mask))

    def encode_contact(self, graph: Graph, accumulate: bool) -> Tensor:
        return self.contact_encoder(self.contact_normalizer(graph.contact_features, accumulate, graph.contact_mask))
