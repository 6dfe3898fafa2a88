"""Training: the frames of a split as a ``Dataset`` (:mod:`~hcmt.training.dataset`), the loop
(:class:`~hcmt.training.trainer.Trainer`), its schedule and its process plumbing (:mod:`~hcmt.training.runtime`),
and :func:`train`, the one entry (``hcmt.train``, ``hcmt train``)."""

from __future__ import annotations

import os
import shutil
from collections.abc import Callable
from pathlib import Path

from hcmt.config import as_config, default_threads, override_list
from hcmt.data.runs import RunFolder, check_start
from hcmt.errors import InputError
from hcmt.files import check_apart
from hcmt.training.runtime import deterministic_scope, lock_run
from hcmt.training.start import check_data, check_model, check_paths, inherit
from hcmt.training.trainer import Trainer


def train(
    config,
    data,
    model: str | None,
    out,
    *,
    overrides=None,
    resume: bool = False,
    overwrite: bool = False,
    ablation: str | None = None,
    seed: int = 0,
    device: str | None = None,
    progress: bool = True,
    stop_at: int | None = None,
    init: str | None = None,
    init_normalizers: str = "keep",
) -> dict:
    """Train ``model`` (``hcmt``, ``mgn``, ``gt``) on the native dataset ``data`` into the run folder ``out``;
    returns the training summary (final loss, steps, ms per step, best validation metric); :meth:`hcmt.Run.load`
    (``out``) gives the trained model.

    ``config`` is a :class:`hcmt.config.Config`, a config mapping, a built-in config name or a YAML path;
    ``overrides`` a list of ``section.key=value`` (``ablation`` is short for ``model.ablation``; ``no-remesh``, an
    alias, sets ``data.remesh=false``); ``resume=True`` continues the run in ``out`` exactly, ``overwrite=True``
    deletes it and starts afresh (otherwise a folder holding a run is refused). ``stop_at`` ends this call after
    that global step (checkpointed), as an interruption would.
    The run folder is locked while training (a second process writing the same ``out`` is refused at once), and a
    run that fails before its first checkpoint leaves nothing behind.

    ``init`` (a run folder or ``pretrained:NAME``) starts from that model's weights (fine-tuning): the run takes its
    ``model:`` settings (and its whole config when ``config`` is None, its model when ``model`` is None); an
    override changing its architecture is refused in one line listing what differs; ``init_normalizers`` ``keep``
    freezes its normalizer statistics, ``reaccumulate`` zeroes them and accumulates them on ``data``. run.yaml
    records it. Threads: torch's count where the caller set one, else the command's default (``--threads auto``,
    :func:`hcmt.config.default_threads`)."""
    cfg, model = _start(
        config, data, model, out, overrides=overrides, resume=resume, overwrite=overwrite, ablation=ablation, init=init
    )
    out, folder = Path(out), RunFolder(out, must_exist=False)
    default_threads()

    def run() -> dict:
        with deterministic_scope():  # train.deterministic holds for this run only
            return Trainer(
                cfg,
                data,
                model,
                out,
                seed=seed,
                resume=resume,
                device=device,
                progress=progress,
                init=init,
                init_normalizers=init_normalizers,
            ).run(stop_at)

    if int(os.environ.get("RANK", 0)) != 0:  # torchrun's other ranks: rank 0 owns the folder
        return run()
    return _locked(run, out, folder, resume)


def _locked(run: Callable[[], dict], out: Path, folder: RunFolder, resume: bool) -> dict:
    """``run()`` with the run folder ``out`` created and locked; a failure before the first checkpoint undoes it."""
    created = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    lock = lock_run(out)
    try:
        return run()
    except BaseException:
        if not folder.latest.is_file():  # nothing worth keeping: leave no run folder behind
            if created:
                lock.unlink(missing_ok=True)
                shutil.rmtree(out, ignore_errors=True)
            elif not resume:
                folder.run_yaml.unlink(missing_ok=True)
        raise
    finally:
        lock.unlink(missing_ok=True)


def _start(config, data, model, out, *, overrides, resume: bool, overwrite: bool, ablation, init):
    """:func:`train`'s config and model, every check done before anything is written or deleted (a bad config or
    data of another dataset leaves a run that ``overwrite`` would replace in place); then ``overwrite``'s deletion
    and the run folder's start rules (:func:`hcmt.data.runs.check_start`)."""
    check_paths(data=data, out=out)
    if resume and overwrite:
        raise InputError("hcmt.train: resume=True and overwrite=True contradict each other; choose one")
    given = config
    config, model = inherit(init, config, model) if init is not None and not resume else (config, model)
    model = check_model(config, model)
    out = Path(out)
    check_apart(
        {"out": out},
        {"data": data, "init": None if str(init or "").startswith("pretrained:") else init},
        owned=("out",),
    )
    overrides = override_list(overrides) + ([f"model.ablation={ablation}"] if ablation else [])
    cfg = as_config(config, overrides).for_training()
    check_data(cfg, data, given, init, overrides)  # a config of another dataset than the data's
    folder = RunFolder(out, must_exist=False)
    if folder.holds_run() and not resume and overwrite:
        shutil.rmtree(out)
        folder = RunFolder(out, must_exist=False)
    check_start(folder, resume)
    return cfg, model


__all__ = ["Trainer", "train"]
