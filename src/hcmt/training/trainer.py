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
How the model and the data are built, and the speed options (``train.*``): :mod:`hcmt.training.build`."""

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
from hcmt.data.runs import RunFolder
from hcmt.domains.adapters import config_adapter
from hcmt.domains.frames import step_seed
from hcmt.domains.spec import model_args
from hcmt.inference.evaluate import validation_rmse
from hcmt.models import checkpoint_state
from hcmt.training.build import adam, build_model, item_forward, step_model, training_data, training_device
from hcmt.training.dataset import StepSampler, step_loader
from hcmt.training.policy import policy_of
from hcmt.training.runtime import (
    InterruptFlag,
    TrainingInterrupted,
    distributed,
    rank_zero_logging,
    run_summary,
    save_atomic,
    say_no_tensorboard,
    step_times,
    stop_together,
    summary_writer,
)
from hcmt.training.start import resume_state, start_record, write_start

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
        self.device = training_device(device, self.rank)
        cfg = cfg.for_training()
        self.cfg, self.tc, self.out, self.seed, self.model_name = cfg, cfg.train, out, seed, model_name
        self.steps, self.policy, self.progress = cfg.train.steps, policy_of(cfg.train), progress
        self.adapter, self.args = config_adapter(cfg), model_args(cfg, model_name, read_meta(data))
        self.folder = RunFolder(out, must_exist=False)
        self.ckpt_path = self.folder.latest
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
        self.model, self.compile = build_model(self.args, self.tc, seed, self.device, source, init_normalizers)
        self.frozen_normalizers = bool(run.get("init")) and run["init"]["normalizers"] == "keep"
        self.normalizer_steps = 0 if self.frozen_normalizers else self.tc.normalizer_steps
        self.bf16 = self.tc.precision == "bf16"  # autocast forward and loss in bfloat16
        self.radius = self.tc.contact_radius
        self.frames, self.valid_trajs = training_data(data, cfg, self.adapter, self.args, seed)
        self.opt = adam(self.model, self.tc.lr, self.policy.adam_epsilon)
        self.step_count, self.best = 0, math.inf
        if resume:
            self._resume()
        if self.rank == 0:  # every check passed: only now is the run folder written (a refused start changes nothing)
            write_start(self.folder, run, data, self._kept_log if resume else None)
        self.net, self.pad, self.dynamic = step_model(
            self.model, self.compile, self.world, self.device, self.frames, self.tc.batch_size
        )
        self._open_logs(resume)

    def _open_logs(self, resume: bool) -> None:
        """Open the run's logs (TensorBoard, log.jsonl, the text log) and announce the run in them."""
        self.writer = (
            summary_writer(self.folder.tensorboard, self.step_count if resume else None) if self.rank == 0 else None
        )
        self.log = open(self.folder.log, "a") if self.rank == 0 else None
        self._handler = rank_zero_logging(self.rank, self.folder.text_log)
        logger.info(
            "%s: %s on %s, %d training frames, steps %d -> %d",
            self.out,
            self.model_name,
            self.device,
            len(self.frames),
            self.step_count,
            self.steps,
        )
        say_no_tensorboard(self.writer)

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
        forward = item_forward(self.model, self.net, self.compile, self.world, self.dynamic, self.pad)
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
        summary = run_summary(self.step_count, loss, times, self.best, self.world, self.device)
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
