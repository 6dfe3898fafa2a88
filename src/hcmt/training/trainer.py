"""Training as the paper does it (Appendix "Hyperparameter Details"): one-step MSE on normalized velocity (or
acceleration) and stress, Gaussian noise on NORMAL nodes' positions with the target corrected (GNS/MGN), Adam,
exponential learning-rate decay from ``lr`` to ``lr_final`` over the run, batch size 1 by default.

A run folder holds ``run.yaml`` (everything needed to rebuild the model), ``checkpoint.pt`` (latest) and ``best.pt``
(best validation rollout), ``log.jsonl``, TensorBoard scalars under ``tb/`` (with the ``tensorboard`` extra) and
``train_stats.json``. Checkpoints are written atomically. ``resume=True`` continues exactly: model, optimizer,
normalizers and step are restored; the learning rate (:func:`learning_rate`), the data order and every random draw
(noise, LPE sign flips) are pure functions of (seed, step, rank), so a run stopped and resumed ends with the same
parameters as one that never stopped. Normalizer statistics accumulate through training (MeshGraphNets); the first
``normalizer_steps`` steps only accumulate them, without parameter updates.

Several processes: under ``torchrun`` (``WORLD_SIZE`` set by it) training uses DistributedDataParallel with gloo on
CPU and NCCL on GPU; each rank takes its share of the shared permutation. DDP broadcasts buffers from rank 0 at
every forward, so the normalizers' statistics are rank 0's (a sample of the data, like any running statistic) and
every rank normalizes its inputs alike; a non-finite loss on any rank stops all of them. Validation rollouts run on
rank 0 while the others wait in the next all-reduce (keep them shorter than the backend's timeout).

Speed options (``train.*``; the defaults are the exact eager step): ``workers`` (graphs built by DataLoader
processes), ``precision: bf16`` (autocast), ``checkpoint_blocks`` (activation checkpointing per block),
``compile`` (``torch.compile`` of the model on **padded** graphs: every batch is brought to static sizes by
:func:`hcmt.graph.batch.pad_graph` in the DataLoader, contact edges to a few bucket sizes, so the compiled step sees
few shapes and CUDA graphs (``reduce-overhead``) can replay it; the normalizers accumulate eagerly before the
compiled forward, which then mutates no buffer; under DDP every rank then normalizes with rank 0's statistics
of the step, as DDP broadcasts buffers), ``deterministic`` (deterministic CUDA kernels and cuBLAS workspace: a
resumed CUDA run ends bit for bit like an unbroken one, at a cost in speed; CPU runs are exact without it; the
cuBLAS setting is read when CUDA is first used, so in a process that used CUDA before, export
``CUBLAS_WORKSPACE_CONFIG=:4096:8`` before starting it).
"""
from __future__ import annotations

import json
import logging
import math
import os
import sys
import time
from pathlib import Path

import numpy as np
import torch
import torch.distributed as dist
from tqdm import tqdm

from hcmt.config import INIT_NORMALIZERS, Config
from hcmt.data.format import read_meta
from hcmt.data.runs import RunFolder, check_start, read_checkpoint
from hcmt.domains.adapters import config_adapter, model_args, noise_gamma, own_args
from hcmt.domains.frames import step_seed
from hcmt.domains.trajectory import load_split
from hcmt.errors import InputError
from hcmt.files import atomic_path
from hcmt.inference.evaluate import validation_rmse
from hcmt.inference.run import Run
from hcmt.models import Normalizer, checkpoint_state, make_model, resolve_device, uses_hierarchy
from hcmt.models.base import compile_simulator, resolve_compile
from hcmt.training.dataset import FrameDataset, StepSampler, pad_sizes, step_loader
from hcmt.training.runtime import (
    InterruptFlag,
    TrainingInterrupted,
    check_resume,
    distributed,
    rank_zero_logging,
    save_atomic,
    stop_together,
)
from hcmt.training.schedule import keras_epsilon, learning_rate

logger = logging.getLogger("hcmt.train")  # rank-zero messages (hcmt.training.runtime.rank_zero_logging)
_no_tensorboard_said = False  # the info line that no TensorBoard scalars are written: once per process


class _NoScalars:
    """Stands in for TensorBoard's ``SummaryWriter`` when tensorboard is not installed: writes nothing (the
    scalars are in log.jsonl all the same)."""

    def add_scalar(self, *args, **kwargs) -> None:
        pass

    def close(self) -> None:
        pass


def summary_writer(folder: Path, purge_step: int | None):
    """TensorBoard's ``SummaryWriter`` on ``folder`` (``tb/``), or :class:`_NoScalars` without the ``tensorboard``
    extra (``pip install 'hcmt[tensorboard]'``)."""
    try:
        from torch.utils.tensorboard import SummaryWriter
    except ImportError:
        return _NoScalars()
    return SummaryWriter(str(folder), purge_step=purge_step)


def _say_no_tensorboard() -> None:
    global _no_tensorboard_said
    if not _no_tensorboard_said:
        _no_tensorboard_said = True
        logger.info("no TensorBoard scalars: tensorboard is not installed (pip install 'hcmt[tensorboard]'); "
                    "log.jsonl has them")


def init_source(init: str, args: dict) -> Run:
    """The model a run starts from (a run folder's best checkpoint or ``pretrained:NAME``), refused in one line
    listing what differs when its constructor arguments (architecture, feature widths) are not this run's."""
    source = Run.load(init, "cpu")
    theirs = own_args(source.info["model"])  # a model saved before MODEL_KEYS held other models' keys too
    differ = [f"{k} {theirs.get(k)!r} there, {args.get(k)!r} here" for k in sorted(set(theirs) | set(args))
              if theirs.get(k) != args.get(k)]
    if differ:
        raise InputError(f"{init}: its model differs from this run's: {'; '.join(differ)}; fine-tuning needs the "
                         "same model, architecture and feature widths (train with the config it was trained with)",
                         param="init")
    return source


def step_times(times: list[tuple[float, float]]) -> dict:
    """Median wall time and CPU time (this process, all its threads: robust to other load on one thread) per step,
    in ms, of ``(wall s, cpu s)`` pairs."""
    wall, cpu = (1e3 * float(np.median([t[k] for t in times])) if times else None for k in (0, 1))
    return {"ms_per_step": wall, "cpu_ms_per_step": cpu}


class Trainer:
    """One training run in four parts a reader can follow: :meth:`__init__` (setup: config, run folder, model,
    data, optimizer, resume), :meth:`step` (one optimizer step on one batch), :meth:`validate` (validation
    rollouts, best.pt) and :meth:`save` (checkpoints); :meth:`run` loops over them."""

    def __init__(self, cfg: Config, data, model_name: str, out: Path, *, ablation, seed: int, resume: bool, device,
                 progress: bool, init: str | None = None, init_normalizers: str = "keep"):
        self.rank, self.world = distributed()
        self.device = resolve_device(device) if device else (
            torch.device(f"cuda:{self.rank}") if torch.cuda.is_available() else torch.device("cpu"))
        cfg = cfg.for_training()
        self.cfg, self.tc, self.out, self.seed, self.model_name = cfg, cfg.train, out, seed, model_name
        tc = self.tc
        self.steps = tc.steps
        meta = read_meta(data)
        self.adapter = config_adapter(cfg)
        self.args = model_args(cfg, model_name, ablation, meta)
        self.folder = RunFolder(out, must_exist=False)
        self.ckpt_path = self.folder.latest
        if resume or self.ckpt_path.is_file():  # train() has cleared or refused a folder holding only run.yaml
            check_start(self.folder, resume, flags=True)
        run = {"model": self.args, "config": cfg, "data": str(Path(data).resolve()), "seed": seed,
               "world_size": self.world}
        if init_normalizers not in INIT_NORMALIZERS:
            raise InputError(f"init_normalizers must be one of {', '.join(INIT_NORMALIZERS)}, got {init_normalizers!r}")
        if resume and init is not None:
            raise InputError("starts a run from another model's weights and resuming continues a run (whose "
                             "run.yaml remembers where it started); give one of them", param="init")
        source, started_from = None, None
        if resume and self.folder.info is not None and init is None:  # the checkpoint holds the weights already
            started_from = self.folder.info.get("init")
        elif init is not None:
            source = init_source(init, self.args)  # refused before anything is written
            started_from = {"from": source.source, "normalizers": init_normalizers,
                            "step": int(source.checkpoint_step)}
        if started_from:
            run["init"] = started_from
        if resume and self.folder.info is not None:
            check_resume(self.folder.info, run, out)

        lpe = self.args.get("ablation") == "lpe"
        self.compile = resolve_compile(tc.compile, steps=tc.steps, device=self.device, lpe=lpe)
        if self.compile != "none" and lpe:
            raise InputError("train.compile: the lpe ablation computes its eigenvectors per graph outside the model's "
                             "tensors; use train.compile=none with it")
        if tc.deterministic:
            # cuBLAS needs this workspace setting for reproducible matmuls (read when its handle is created)
            os.environ.setdefault("CUBLAS_WORKSPACE_CONFIG", ":4096:8")
            torch.use_deterministic_algorithms(True)
            torch.backends.cudnn.benchmark = False
        torch.manual_seed(seed)  # parameter initialization
        self.model = make_model(self.args).to(self.device)
        # fine-tuning from another model's weights: its normalizers kept (frozen) or re-accumulated on this data
        self.frozen_normalizers = bool(started_from) and started_from["normalizers"] == "keep"
        if source is not None and not resume:
            self.model.load_state_dict(source.model.state_dict())
            if init_normalizers == "reaccumulate":
                for m in self.model.modules():
                    if isinstance(m, Normalizer):
                        m.reset()
        self.normalizer_steps = 0 if self.frozen_normalizers else tc.normalizer_steps
        self.model.checkpoint_blocks = tc.checkpoint_blocks  # memory for recomputation
        self.bf16 = tc.precision == "bf16"  # autocast forward and loss in bfloat16
        levels, remesh = uses_hierarchy(self.args)
        self.radius = tc.contact_radius
        self.frames = FrameDataset(data, "train", self.adapter, levels, remesh, self.radius,
                                   tc.noise_std, noise_gamma(cfg, self.adapter), seed,
                                   cfg.data.exclude_trajectories, tc.noise_nodes, in_memory=cfg.data.in_memory)
        # pushforward: with this probability a frame's input is the model's own prediction (frames.pushforward_item)
        self.pushforward = tc.pushforward
        self.pushforward_start = tc.pushforward_start
        self.valid_trajs = (load_split(data, "valid", self.adapter, levels, remesh,
                                       limit=tc.valid_trajectories)
                            if (Path(data) / "valid.h5").is_file() else [])
        # fused: one kernel for every parameter, on CUDA and on the CPU (3.1 against 11-13 ms of CPU per step for the
        # small HCMT's 199 tensors); it agrees with the per-tensor Adam within float32 rounding (test_speed_options)
        self.opt = torch.optim.Adam(self.model.parameters(), lr=tc.lr, eps=tc.adam_epsilon or 1e-8, fused=True)
        self.step_count, self.best = 0, math.inf
        if resume:
            self._resume()
        if self.rank == 0:  # every check passed: only now is the run folder written (a refused start changes nothing)
            out.mkdir(parents=True, exist_ok=True)
            self.folder.write_info(run)
            self.folder.write_data_facts(data)
            if resume:
                self._trim_log()
        self.net = self.model
        if self.world > 1:
            self.net = torch.nn.parallel.DistributedDataParallel(
                self.model, device_ids=[self.device.index] if self.device.type == "cuda" else None)
        self.pad = None
        if self.compile != "none":  # static shapes: padded batches, one compiled graph per contact bucket
            self.pad = pad_sizes(self.frames, tc.batch_size)
            self.net = compile_simulator(self.net, self.compile)
        self.writer = self.log = None
        if self.rank == 0:
            self.writer = summary_writer(self.folder.tensorboard, self.step_count if resume else None)
            self.log = open(self.folder.log, "a")
        self.progress = progress
        self._handler = rank_zero_logging(self.rank, self.folder.text_log)
        logger.info("%s: %s on %s, %d training frames, steps %d -> %d", out, model_name, self.device,
                    len(self.frames), self.step_count, self.steps)
        if isinstance(self.writer, _NoScalars):
            _say_no_tensorboard()

    def _resume(self) -> None:
        state = read_checkpoint(self.ckpt_path, self.device, earlier=self.folder.best)
        try:
            self.model.load_state_dict(state["model"])
            self.opt.load_state_dict(state["optimizer"])
        except (KeyError, RuntimeError, ValueError) as exc:
            raise InputError(f"{self.ckpt_path}: the checkpoint does not fit this run's model or optimizer "
                             f"({exc.__class__.__name__}); resuming continues only the run that wrote it") from None
        self.step_count, self.best = int(state["step"]), float(state["best"])
        if self.step_count > self.steps:
            raise InputError(f"{self.out}: train.steps {self.steps}, but the run has done {self.step_count} steps; a "
                             "run only grows (train.steps, --steps in hcmt train, >= the steps done)")
        self._kept_log = ([r for r in self.folder.log_records() if r["step"] <= self.step_count]
                          if self.rank == 0 and self.folder.log.is_file() else None)  # read (and checked) here

    def _trim_log(self) -> None:
        """Drop what was logged after the resumed checkpoint: no duplicate steps."""
        if self._kept_log is not None:
            with atomic_path(self.folder.log) as tmp:
                tmp.write_text("".join(json.dumps(r) + "\n" for r in self._kept_log))

    def _loss_denominator(self, graph, mask) -> torch.Tensor:
        """``train.loss_denominator``: ``masked`` (hcmt: the number of unmasked entries, a mean over what is
        predicted) or ``nodes`` (the authors' model.py: ``reduce_mean`` over all N nodes of the masked error summed
        over channels)."""
        if self.tc.loss_denominator == "nodes":
            n = graph.node_mask.sum() if graph.node_mask is not None else torch.tensor(float(graph.num_nodes))
            return n.to(mask.device, torch.float32).clamp_min(1.0)
        return mask.sum().clamp_min(1.0)

    def _epsilon_hat(self) -> float:
        t = self.step_count - self.normalizer_steps + 1  # this optimizer step, 1-based
        return keras_epsilon(self.tc.adam_epsilon or 1e-7, self.opt.param_groups[0]["betas"][1], t)

    def _pushforward_probability(self) -> float:
        """``train.pushforward`` from ``train.pushforward_start`` on (and never while only the normalizers learn)."""
        start = max(self.pushforward_start, self.normalizer_steps)
        return self.pushforward if self.step_count >= start else 0.0

    def learning_rate(self, step: int) -> float:
        tc = self.tc
        return learning_rate(step, self.steps, tc.lr, tc.lr_final or tc.lr, tc.lr_decay_steps, tc.lr_decay_rate)

    def step(self, graph, tgt, mask) -> tuple[float, float]:
        """One training step (normalizer statistics only during the first ``normalizer_steps``): (loss, lr)."""
        torch.manual_seed(step_seed(self.seed, self.step_count, self.rank))  # global draws (LPE sign flips)
        graph, tgt, mask = graph.to(self.device), tgt.to(self.device), mask.to(self.device)
        tc, warmup = self.tc, self.step_count < self.normalizer_steps
        # the authors' loop (run_model.py) accumulates only the node normalizer while warming up
        accumulate = not (warmup and tc.normalizer_warmup == "nodes") and not self.frozen_normalizers
        with torch.autocast(self.device.type, dtype=torch.bfloat16, enabled=self.bf16):
            if not accumulate and not self.frozen_normalizers:
                self.model.node_normalizer.accumulate(graph.node_features, graph.node_mask)
            elif accumulate and tc.mesh_edges_twice and graph.level_edges:  # the authors' HCMT: level 0 twice
                self.model.mesh_normalizer.accumulate(graph.mesh_features, graph.mesh_mask)
            if self.pad is None:
                pred = self.net(graph, accumulate=accumulate)
                norm_tgt = self.model.normalize_target(tgt, accumulate=accumulate)
            else:  # compiled: the same statistics, accumulated eagerly, then a forward that mutates no buffer
                if accumulate:
                    self.model.accumulate(graph, tgt)
                pred = self.net(graph, accumulate=False)
                norm_tgt = self.model.normalize_target(tgt, accumulate=False)
            loss = ((pred.float() - norm_tgt.float()) ** 2 * mask).sum() / self._loss_denominator(graph, mask)
        lr = self.learning_rate(self.step_count)
        if not warmup:
            for group in self.opt.param_groups:
                group["lr"] = lr
                if tc.adam_epsilon_hat:  # TF/Keras Adam's ε̂ (see _epsilon_hat)
                    group["eps"] = self._epsilon_hat()
            self.opt.zero_grad(set_to_none=True)
            loss.backward()
            self.opt.step()
        elif self.world > 1:  # keep DDP's reducer in step: a zero-gradient backward
            (loss * 0).backward()
        self.step_count += 1
        return float(loss.detach()), lr

    def validate(self) -> None:
        """Validation rollouts (rank 0); a better position RMSE-all writes best.pt."""
        metrics = validation_rmse(self.model, self.adapter, self.valid_trajs, self.radius)
        self.model.train()
        for k, v in metrics.items():
            self.writer.add_scalar(k, v, self.step_count)
        self._record({"step": self.step_count, **metrics})
        logger.info("step %d: %s", self.step_count, ", ".join(f"{k} {v:.4g}" for k, v in metrics.items()))
        if metrics["valid/position_rmse_all"] < self.best:
            self.best = metrics["valid/position_rmse_all"]
            self.save(self.folder.best)

    def save(self, path: Path) -> None:
        save_atomic(checkpoint_state(self.model, self.args, optimizer=self.opt.state_dict(), step=self.step_count,
                                     best=self.best), path)

    def _record(self, rec: dict) -> None:
        self.log.write(json.dumps(rec) + "\n")
        self.log.flush()

    def run(self, stop_at: int | None = None) -> dict:
        tc, rank = self.tc, self.rank
        log_every, ckpt_every = tc.log_every, tc.checkpoint_every
        valid_every = tc.valid_every
        end = self.steps if stop_at is None else min(self.steps, int(stop_at))
        bar = tqdm(total=self.steps, initial=self.step_count, disable=not self.progress or rank != 0,
                   desc=f"train {self.model_name}", dynamic_ncols=True,
                   mininterval=0.1 if sys.stderr.isatty() else 30.0)
        workers = tc.workers
        sampler = StepSampler(self.frames, tc.batch_size, self.seed, self.step_count, end, self.world,
                              rank)
        pushforward = (lambda key: self.frames.pushforward_item(key, self.model, self._pushforward_probability())
                       ) if self.pushforward > 0 else None
        loader = step_loader(self.frames, sampler, self.pad, workers, pushforward)
        times, loss = [], float("nan")
        interrupted = InterruptFlag()  # Ctrl-C / SIGTERM end the current step, then save and stop
        self.model.train()
        try:
            while self.step_count < end:
                t0, c0 = time.perf_counter(), time.process_time()
                loss, lr = self.step(*next(loader))
                times.append((time.perf_counter() - t0, time.process_time() - c0))  # wall and this process's CPU
                finite, stop = stop_together(self.world, self.device, loss, interrupted.set)
                step = self.step_count
                if not finite:
                    raise FloatingPointError(f"loss became non-finite at step {step} (rank {rank}: {loss}); lower "
                                             "train.lr or check the data")
                bar.update(1)
                if rank == 0 and (step % log_every == 0 or step == self.steps):
                    bar.set_postfix(loss=f"{loss:.4g}", lr=f"{lr:.2e}")
                    self.writer.add_scalar("train/loss", loss, step)
                    self.writer.add_scalar("train/lr", lr, step)
                    self._record({"step": step, "loss": loss, "lr": lr, **step_times(times[-log_every:])})
                if rank == 0 and self.valid_trajs and valid_every and (step % valid_every == 0 or step == self.steps):
                    self.validate()
                if rank == 0 and (step % ckpt_every == 0 or step == end or stop):
                    self.save(self.ckpt_path)
                if stop:
                    logger.info("interrupted at step %d: checkpoint saved", step)
                    raise TrainingInterrupted(f"interrupted: checkpoint of step {step} of {self.steps} saved in "
                                              f"{self.ckpt_path}")
        finally:
            interrupted.restore()
            bar.close()
            if rank == 0:
                self.writer.close()
                self.log.close()
        summary = self._finish(times, loss)
        if self._handler is not None:
            logging.getLogger("hcmt").removeHandler(self._handler)
            self._handler.close()
        return summary

    def _finish(self, times: list[float], loss: float) -> dict:
        summary = {"steps": self.step_count, "final_loss": loss,
                   **{f"train_{k}": v for k, v in step_times(times).items()},
                   "best_valid_position_rmse_all": self.best if math.isfinite(self.best) else None,
                   "world_size": self.world, "device": str(self.device)}
        if self.rank == 0 and self.step_count == self.steps:
            if not self.folder.best.is_file():
                self.save(self.folder.best)
            self.folder.write_stats(summary)
            logger.info("%s: finished %d steps, %.1f ms per step", self.out, self.step_count,
                        summary["train_ms_per_step"] or float("nan"))
        if self.world > 1:
            dist.barrier()
        return summary
