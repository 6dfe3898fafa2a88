"""What a training run is built from before its first step: the device, the model (compile mode, fine-tuning
weights, normalizers kept or reset), the training frames and validation trajectories, the fused Adam, and the model
the step calls (DDP, compiled, padded shapes). Each is a function of the config and the run's start record, so the
loop that uses them (:class:`~hcmt.training.trainer.Trainer`) reads as the loop, and how the speed options shape a
run reads here.

Speed options (``train.*``): ``workers`` (DataLoader processes build the graphs), ``precision: bf16`` (autocast),
``checkpoint_blocks`` (activation checkpointing per block), ``compile`` (default ``auto``: compiled in runs of 5,000
steps or more, :func:`hcmt.models.base.resolve_compile`; on the CPU in mode ``default`` with symbolic sizes on the
graphs as they are, otherwise on graphs padded to static sizes, :func:`hcmt.graph.batch.pad_graph`, contact edges in
buckets, so CUDA graphs can replay the step; the normalizers accumulate eagerly before the compiled forward, which
mutates no buffer), ``deterministic`` (:func:`~hcmt.training.runtime.deterministic_kernels`: a resumed CUDA run ends
bit for bit like an unbroken one, at a cost in speed; CPU runs are exact without it)."""

from __future__ import annotations

from pathlib import Path

import torch

from hcmt.config import Config, TrainConfig
from hcmt.domains.adapters import Adapter, noise_gamma
from hcmt.domains.trajectory import load_split
from hcmt.errors import InputError
from hcmt.graph.batch import PadSizes
from hcmt.models import Normalizer, make_model, resolve_device, uses_hierarchy
from hcmt.models.base import compile_simulator, resolve_compile
from hcmt.training.dataset import FrameDataset, pad_sizes, padded_forward
from hcmt.training.runtime import deterministic_kernels


def training_device(device, rank: int) -> torch.device:
    """``device`` when given, else this rank's GPU when there is one, else the CPU."""
    return (
        resolve_device(device)
        if device
        else (torch.device(f"cuda:{rank}") if torch.cuda.is_available() else torch.device("cpu"))
    )


def build_model(args: dict, tc: TrainConfig, seed: int, device: torch.device, source, init_normalizers: str):
    """The model on its device and its compile mode, from ``source``'s weights when fine-tuning: its normalizers
    kept (frozen) or re-accumulated on this data."""
    lpe = args.get("ablation") == "lpe"  # auto: eager for it; an explicit mode: refused
    mode = resolve_compile(tc.compile, steps=tc.steps, device=device, lpe=lpe)
    if mode != "none" and lpe:
        raise InputError(
            "train.compile: the lpe ablation computes its eigenvectors per graph outside the model's "
            "tensors; use train.compile=none with it"
        )
    if tc.deterministic:
        deterministic_kernels()
    torch.manual_seed(seed)  # parameter initialization
    model = make_model(args).to(device)
    if source is not None:
        model.load_state_dict(source.model.state_dict())
        for m in model.modules() if init_normalizers == "reaccumulate" else ():
            if isinstance(m, Normalizer):
                m.reset()  # statistics counted afresh on this data
    model.checkpoint_blocks = tc.checkpoint_blocks  # memory for recomputation
    return model, mode


def adam(model, lr: float, eps: float) -> torch.optim.Adam:
    """The run's Adam at learning rate ``lr`` with ε ``eps`` (the step sets both per optimizer step)."""
    # fused: one kernel for every parameter, on CUDA and on the CPU (3.1 against 11-13 ms of CPU per step for the
    # small HCMT's 199 tensors); it agrees with the per-tensor Adam within float32 rounding (test_speed_options)
    return torch.optim.Adam(model.parameters(), lr=lr, eps=eps, fused=True)


def training_data(data, cfg: Config, adapter: Adapter, args: dict, seed: int) -> tuple[FrameDataset, list]:
    """The training frames and the validation trajectories."""
    tc = cfg.train
    levels, remesh = uses_hierarchy(args, cfg.data.remesh)
    frames = FrameDataset(
        data,
        "train",
        adapter,
        levels,
        remesh,
        tc.contact_radius,
        tc.noise_std,
        noise_gamma(cfg, adapter),
        seed,
        cfg.data.exclude_trajectories,
        tc.noise_nodes,
        in_memory=cfg.data.in_memory,
        contact_free_weight=tc.contact_free_weight,
    )
    valid_trajs = (
        load_split(data, "valid", adapter, levels, remesh, limit=tc.valid_trajectories)
        if (Path(data) / "valid.h5").is_file()
        else []
    )
    return frames, valid_trajs


def step_model(model, mode: str, world: int, device: torch.device, frames: FrameDataset, batch: int):
    """(net, pad, dynamic): the model the step calls, under DDP with several processes, compiled: on the CPU in mode
    ``default`` with symbolic sizes on the graphs as they are (no padding; one compiled graph for every mesh and
    contact count, as rollouts), else on padded batches of static shapes (CUDA graphs need them)."""
    net = model
    if world > 1:
        net = torch.nn.parallel.DistributedDataParallel(
            model, device_ids=[device.index] if device.type == "cuda" else None
        )
    pad = None  # padded compiles: static shapes, padded batches, contact edges bucketed
    dynamic = mode == "default" and device.type == "cpu"
    if mode != "none":
        pad = None if dynamic else pad_sizes(frames, batch)
        net = compile_simulator(net, mode, dynamic=dynamic)
    return net, pad, dynamic


def item_forward(model, net, mode: str, world: int, dynamic: bool, pad: PadSizes | None):
    """The forward a pushforward item's prediction goes through: the compiled one when the model compiles (on
    padded graphs when the step's are), None when eager."""
    forward = None  # eager: the model itself
    if mode != "none":
        net = (
            net
            if world == 1  # DDP's forward would sync buffers
            else compile_simulator(model, mode, dynamic=dynamic)
        )
        forward = padded_forward(net, pad) if pad is not None else (lambda graph: net(graph, accumulate=False))
    return forward
