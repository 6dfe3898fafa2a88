"""Training as the paper does it (Appendix "Hyperparameter Details"): one-step MSE on normalized velocity (or
acceleration) and stress, Gaussian noise on NORMAL nodes' positions with the target corrected (GNS/MGN), Adam,
exponential learning-rate decay from ``lr`` to ``lr_final`` over the run, batch size 1 by default.

A run folder holds ``run.yaml`` (everything needed to rebuild the model), ``checkpoint.pt`` (latest), ``best.pt``
(best validation rollout), ``step_<N>.pt`` (every ``train.keep_every`` steps, when set), ``log.jsonl``, TensorBoard
scalars under ``tb/`` (with the ``tensorboard`` extra) and ``train_stats.json``. Checkpoints are written atomically.
``resume=True`` continues exactly: model, optimizer, normalizers and step are restored; the learning rate
(:func:`learning_rate`), the data order and every random draw (noise, LPE sign flips) are pure functions of (seed,
step, rank), so a run stopped and resumed ends with the same parameters as one that never stopped. Normalizer
statistics accumulate through training (MeshGraphNets); the first ``normalizer_steps`` steps only accumulate them,
without parameter updates. The loop's conventions (normalizer warm-up, loss denominator, Adam's ε, step decay) are
``train.policy``'s: :mod:`hcmt.training.policy`. Several processes (``torchrun``): :mod:`hcmt.training.runtime`.
Speed options (``train.*``): ``workers`` (DataLoader processes build the graphs), ``precision: bf16`` (autocast),
``checkpoint_blocks`` (activation checkpointing per block), ``compile`` (default ``auto``: compiled in runs of 5,000
steps or more, :func:`hcmt.models.base.resolve_compile`; on the CPU in mode ``default`` with symbolic sizes on the
graphs as they are, otherwise on graphs padded to static sizes, :func:`hcmt.graph.batch.pad_graph`, contact edges in
buckets, so CUDA graphs can replay the step; the normalizers accumulate eagerly before the compiled forward, which
mutates no buffer), ``deterministic`` (:func:`~hcmt.training.runtime.deterministic_kernels`: a resumed CUDA run ends
bit for bit like an unbroken one, at a cost in speed; CPU runs are exact without it)."""

from __future__ import annotations

import json
import logging
import math
import sys
import time
from pathlib import Path

import torch
import torch.distributed as dist
from tqdm import tqdm

from hcmt.config import Config
from hcmt.data.format import read_meta
from hcmt.data.runs import RunFolder, check_start
from hcmt.domains.adapters import config_adapter, model_args, noise_gamma
from hcmt.domains.frames import step_seed
from hcmt.domains.trajectory import load_split
from hcmt.errors import InputError
from hcmt.inference.evaluate import validation_rmse
from hcmt.models import Normalizer, checkpoint_state, make_model, resolve_device, uses_hierarchy
from hcmt.models.base import compile_simulator, resolve_compile
from hcmt.training.dataset import FrameDataset, StepSampler, pad_sizes, padded_forward, step_loader
from hcmt.training.policy import policy_of
from hcmt.training.runtime import (
    InterruptFlag,
    TrainingInterrupted,
    deterministic_kernels,
    distributed,
    rank_zero_logging,
    rewrite_log,
    save_atomic,
    say_no_tensorboard,
    step_times,
    stop_together,
    summary_writer,
)
from hcmt.training.start import resume_state, start_record

logger = logging.getLogger("hcmt.train")  # rank-zero messages (hcmt.training.runtime.rank_zero_logging)


class Trainer:
    """One training run in four parts a reader can follow: :meth:`__init__` (setup: config, run folder, model,
    data, optimizer, resume), :meth:`step` (one optimizer step on one batch), :meth:`validate` (validation
    rollouts, best.pt) and :meth:`save` (checkpoints); :meth:`run` loops over them."""

    def __init__(
        self,
        cfg: Config,
        data,
        model_name: str,
        out: Path,
        *,
        seed: int,
        resume: bool,
        device,
        progress: bool,
        init: str | None = None,
        init_normalizers: str = "keep",
    ):
        self.rank, self.world = distributed()
        self.device = (
            resolve_device(device)
            if device
            else (torch.device(f"cuda:{self.rank}") if torch.cuda.is_available() else torch.device("cpu"))
        )
        cfg = cfg.for_training()
        self.cfg, self.tc, self.out, self.seed, self.model_name = cfg, cfg.train, out, seed, model_name
        self.steps, self.policy, self.progress = cfg.train.steps, policy_of(cfg.train), progress
        self.adapter, self.args = config_adapter(cfg), model_args(cfg, model_name, read_meta(data))
        self.folder = RunFolder(out, must_exist=False)
        self.ckpt_path = self.folder.latest
        if resume or self.ckpt_path.is_file():  # train() has cleared or refused a folder holding only run.yaml
            check_start(self.folder, resume, flags=True)
        run, source = start_record(
            self.folder,
            self.args,
            cfg,
            data,
            seed,
            self.world,
            resume=resume,
            init=init,
            init_normalizers=init_normalizers,
        )
        self._build_model(source, run.get("init"), init_normalizers)
        self._build_data(data)
        # fused: one kernel for every parameter, on CUDA and on the CPU (3.1 against 11-13 ms of CPU per step for the
        # small HCMT's 199 tensors); it agrees with the per-tensor Adam within float32 rounding (test_speed_options)
        self.opt = torch.optim.Adam(self.model.parameters(), lr=self.tc.lr, eps=self.policy.adam_epsilon, fused=True)
        self.step_count, self.best = 0, math.inf
        if resume:
            self._resume()
        if self.rank == 0:  # every check passed: only now is the run folder written (a refused start changes nothing)
            out.mkdir(parents=True, exist_ok=True)
            self.folder.write_info(run)
            self.folder.write_data_facts(data)
            if resume and self._kept_log is not None:
                rewrite_log(self.folder.log, self._kept_log)  # what was logged after the checkpoint goes
        self._wrap_model()
        self.writer = (
            summary_writer(self.folder.tensorboard, self.step_count if resume else None) if self.rank == 0 else None
        )
        self.log = open(self.folder.log, "a") if self.rank == 0 else None
        self._handler = rank_zero_logging(self.rank, self.folder.text_log)
        logger.info(
            "%s: %s on %s, %d training frames, steps %d -> %d",
            out,
            model_name,
            self.device,
            len(self.frames),
            self.step_count,
            self.steps,
        )
        say_no_tensorboard(self.writer)

    def _build_model(self, source, started_from: dict | None, init_normalizers: str) -> None:
        """The model on its device, from ``source``'s weights when fine-tuning: its normalizers kept (frozen) or
        re-accumulated on this data."""
        tc = self.tc
        lpe = self.args.get("ablation") == "lpe"  # auto: eager for it; an explicit mode: refused
        self.compile = resolve_compile(tc.compile, steps=tc.steps, device=self.device, lpe=lpe)
        if self.compile != "none" and lpe:
            raise InputError(
                "train.compile: the lpe ablation computes its eigenvectors per graph outside the model's "
                "tensors; use train.compile=none with it"
            )
        if tc.deterministic:
            deterministic_kernels()
        torch.manual_seed(self.seed)  # parameter initialization
        self.model = make_model(self.args).to(self.device)
        self.frozen_normalizers = bool(started_from) and started_from["normalizers"] == "keep"
        if source is not None:
            self.model.load_state_dict(source.model.state_dict())
            for m in self.model.modules() if init_normalizers == "reaccumulate" else ():
                if isinstance(m, Normalizer):
                    m.reset()  # statistics counted afresh on this data
        self.normalizer_steps = 0 if self.frozen_normalizers else tc.normalizer_steps
        self.model.checkpoint_blocks = tc.checkpoint_blocks  # memory for recomputation
        self.bf16 = tc.precision == "bf16"  # autocast forward and loss in bfloat16

    def _build_data(self, data) -> None:
        """The training frames and the validation trajectories."""
        tc, cfg = self.tc, self.cfg
        levels, remesh = uses_hierarchy(self.args, cfg.data.remesh)
        self.radius = tc.contact_radius
        self.frames = FrameDataset(
            data,
            "train",
            self.adapter,
            levels,
            remesh,
            self.radius,
            tc.noise_std,
            noise_gamma(cfg, self.adapter),
            self.seed,
            cfg.data.exclude_trajectories,
            tc.noise_nodes,
            in_memory=cfg.data.in_memory,
            contact_free_weight=tc.contact_free_weight,
        )
        self.valid_trajs = (
            load_split(data, "valid", self.adapter, levels, remesh, limit=tc.valid_trajectories)
            if (Path(data) / "valid.h5").is_file()
            else []
        )

    def _wrap_model(self) -> None:
        """``self.net``: the model the step calls, under DDP with several processes, compiled: on the CPU in mode
        ``default`` with symbolic sizes on the graphs as they are (no padding; one compiled graph for every mesh and
        contact count, as rollouts), else on padded batches of static shapes (CUDA graphs need them)."""
        self.net = self.model
        if self.world > 1:
            self.net = torch.nn.parallel.DistributedDataParallel(
                self.model, device_ids=[self.device.index] if self.device.type == "cuda" else None
            )
        self.pad = None  # padded compiles: static shapes, padded batches, contact edges bucketed
        self.dynamic = self.compile == "default" and self.device.type == "cpu"
        if self.compile != "none":
            self.pad = None if self.dynamic else pad_sizes(self.frames, self.tc.batch_size)
            self.net = compile_simulator(self.net, self.compile, dynamic=self.dynamic)

    def _resume(self) -> None:
        """Model, optimizer, step and best score from the run's latest checkpoint (:func:`resume_state`)."""
        self.step_count, self.best, self._kept_log = resume_state(
            self.folder, self.model, self.opt, self.device, self.steps, self.rank
        )

    def _pushforward_probability(self) -> float:
        """``train.pushforward`` from ``train.pushforward_start`` on (and never while only the normalizers learn)."""
        start = max(self.tc.pushforward_start, self.normalizer_steps)
        return self.tc.pushforward if self.step_count >= start else 0.0

    def learning_rate(self, step: int) -> float:
        return self.policy.learning_rate(step, self.tc)

    def step(self, graph, tgt, mask) -> tuple[float, float]:
        """One training step (normalizer statistics only during the first ``normalizer_steps``): (loss, lr)."""
        torch.manual_seed(step_seed(self.seed, self.step_count, self.rank))  # global draws (LPE sign flips)
        graph, tgt, mask = graph.to(self.device), tgt.to(self.device), mask.to(self.device)
        warmup = self.step_count < self.normalizer_steps
        with torch.autocast(self.device.type, dtype=torch.bfloat16, enabled=self.bf16):
            accumulate = self.policy.accumulate(self.model, graph, warmup, self.frozen_normalizers)
            compiled = self.compile != "none"
            if compiled and accumulate:  # compiled: the statistics eagerly, a forward mutating no buffer
                self.model.accumulate(graph, tgt)
            eager = accumulate and not compiled
            pred = self.net(graph, accumulate=eager)
            norm_tgt = self.model.normalize_target(tgt, accumulate=eager)
            loss = ((pred.float() - norm_tgt.float()) ** 2 * mask).sum() / self.policy.loss_count(graph, mask)
        lr = self.learning_rate(self.step_count)
        if not warmup:
            self._update(loss, lr)
        elif self.world > 1:  # keep DDP's reducer in step: a zero-gradient backward
            (loss * 0).backward()
        self.step_count += 1
        return float(loss.detach()), lr

    def _update(self, loss: torch.Tensor, lr: float) -> None:
        """One Adam step at ``lr`` with the policy's ε for this optimizer step."""
        t = self.step_count - self.normalizer_steps + 1  # this optimizer step, 1-based
        for group in self.opt.param_groups:
            group["lr"], group["eps"] = lr, self.policy.epsilon(t, group["betas"][1])
        self.opt.zero_grad(set_to_none=True)
        loss.backward()
        self.opt.step()

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
        save_atomic(
            checkpoint_state(
                self.model, self.args, optimizer=self.opt.state_dict(), step=self.step_count, best=self.best
            ),
            path,
        )

    def _record(self, rec: dict) -> None:
        self.log.write(json.dumps(rec) + "\n")
        self.log.flush()

    def _loader(self, end: int):
        """This rank's batches of the steps up to ``end`` (pushforward items through the model, compiled if it is)."""
        sampler = StepSampler(self.frames, self.tc.batch_size, self.seed, self.step_count, end, self.world, self.rank)
        forward = None  # eager: the model itself
        if self.compile != "none":
            net = (
                self.net
                if self.world == 1  # DDP's forward would sync buffers
                else compile_simulator(self.model, self.compile, dynamic=self.dynamic)
            )
            forward = (
                padded_forward(net, self.pad) if self.pad is not None else (lambda graph: net(graph, accumulate=False))
            )
        pushforward = (
            (lambda key: self.frames.pushforward_item(key, self.model, self._pushforward_probability(), forward))
            if self.tc.pushforward > 0
            else None
        )
        return step_loader(self.frames, sampler, self.pad, self.tc.workers, pushforward)

    def _report(self, loss: float, lr: float, times: list, end: int, stop: bool) -> None:
        """Rank 0 after a step: log the loss, validate, checkpoint, each at its interval (and at the end)."""
        tc, step = self.tc, self.step_count
        if step % tc.log_every == 0 or step == self.steps:
            self.bar.set_postfix(loss=f"{loss:.4g}", lr=f"{lr:.2e}")
            for k, v in (("train/loss", loss), ("train/lr", lr)):
                self.writer.add_scalar(k, v, step)
            self._record({"step": step, "loss": loss, "lr": lr, **step_times(times[-tc.log_every :])})
        if self.valid_trajs and tc.valid_every and (step % tc.valid_every == 0 or step == self.steps):
            self.validate()
        if step % tc.checkpoint_every == 0 or step == end or stop:
            self.save(self.ckpt_path)
        if tc.keep_every and step % tc.keep_every == 0:
            self.save(self.folder.kept(step))

    def run(self, stop_at: int | None = None) -> dict:
        """Train to ``train.steps`` (or to ``stop_at``, checkpointed, as an interruption would); the summary."""
        end = self.steps if stop_at is None else min(self.steps, int(stop_at))
        self.bar = tqdm(
            total=self.steps,
            initial=self.step_count,
            disable=not self.progress or self.rank != 0,
            desc=f"train {self.model_name}",
            dynamic_ncols=True,
            mininterval=0.1 if sys.stderr.isatty() else 30.0,
        )
        loader = self._loader(end)
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
                    raise FloatingPointError(
                        f"loss became non-finite at step {step} (rank {self.rank}: {loss}); "
                        "lower train.lr or check the data"
                    )
                self.bar.update(1)
                if self.rank == 0:
                    self._report(loss, lr, times, end, stop)
                if stop:
                    logger.info("interrupted at step %d: checkpoint saved", step)
                    raise TrainingInterrupted(
                        f"interrupted: checkpoint of step {step} of {self.steps} saved in {self.ckpt_path}"
                    )
        finally:
            interrupted.restore()
            self.bar.close()
            if self.rank == 0:
                self.writer.close()
                self.log.close()
        summary = self._finish(times, loss)
        if self._handler is not None:
            logging.getLogger("hcmt").removeHandler(self._handler)
            self._handler.close()
        return summary

    def _finish(self, times: list[float], loss: float) -> dict:
        summary = {
            "steps": self.step_count,
            "final_loss": loss,
            **{f"train_{k}": v for k, v in step_times(times).items()},
            "best_valid_position_rmse_all": self.best if math.isfinite(self.best) else None,
            "world_size": self.world,
            "device": str(self.device),
        }
        if self.rank == 0 and self.step_count == self.steps:
            if not self.folder.best.is_file():
                self.save(self.folder.best)
            self.folder.write_stats(summary)
            logger.info(
                "%s: finished %d steps, %.1f ms per step",
                self.out,
                self.step_count,
                summary["train_ms_per_step"] or float("nan"),
            )
        if self.world > 1:
            dist.barrier()
        return summary
