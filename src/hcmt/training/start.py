"""How a run starts: the record ``run.yaml`` keeps (model arguments, config, data, seed, processes, the model it
started from) and the checks before anything is written: a resumed run's settings are the saved ones, a
fine-tuned run's (``--init``) model is its source's, inherited (:func:`inherit`). Once they pass, the run folder is
written (:func:`write_start`)."""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path

from hcmt.config import INIT_NORMALIZERS, MODELS, Config, as_config, check_same_dataset, set_in
from hcmt.data.format import read_meta
from hcmt.data.runs import RunFolder, check_start, read_checkpoint
from hcmt.errors import InputError, clip
from hcmt.inference.run import Run
from hcmt.models import architecture
from hcmt.training.runtime import check_resume, rewrite_log


def init_source(init: str, args: dict) -> Run:
    """The model a run starts from (a run folder's best checkpoint or ``pretrained:NAME``), refused in one line
    listing what differs when its constructor arguments (architecture, feature widths) are not this run's."""
    source = Run.load(init, "cpu")
    theirs, args = architecture(source.info.model), architecture(args)
    differ = [
        f"{k} {theirs.get(k)!r} there, {args.get(k)!r} here"
        for k in sorted(set(theirs) | set(args))
        if theirs.get(k) != args.get(k)
    ]
    if differ:
        raise InputError(
            f"{init}: its model differs from this run's: {'; '.join(differ)}; fine-tuning needs the "
            "same model, architecture and feature widths (train with the config it was trained with)",
            param="init",
        )
    return source


def inherit(init: str, config, model: str | None) -> tuple[Config, str]:
    """A fine-tuned run's config and model: ``config``'s (None: the source's whole config) with the source's
    ``model:`` section (its architecture and input features, so fine-tuning the shipped model needs no ``--set``),
    and the source's model when ``model`` is None. Overrides apply after (a changed architecture is then refused
    by :func:`init_source`, listing what differs)."""
    source = Run.load(init, "cpu")
    cfg = source.config if config is None else replace(as_config(config), model=source.config.model)
    return cfg, model or source.info.model["name"]


def check_model(config, model: str | None) -> str:
    """``model``'s name, refused in one line when unknown, or when it or ``config`` is missing."""
    if config is None or model is None:
        raise InputError("hcmt.train: config and model are needed (only init may leave them out)")
    model = str(model).lower()
    if model not in MODELS:
        raise InputError(f"hcmt.train: unknown model {model!r}; expected one of {', '.join(MODELS)}")
    return model


def check_paths(**paths) -> None:
    """``hcmt.train``'s folders (``data=``, ``out=``): each a path, refused in one line naming the parameter
    otherwise (None, a number)."""
    for name, value in paths.items():
        if not isinstance(value, (str, os.PathLike)) or not str(value).strip():
            what = "the native dataset folder (meta.json + train.h5)" if name == "data" else "the run folder to write"
            raise InputError(f"expected a path, {what}; got {clip(repr(value))}", param=name)


def check_data(cfg: Config, data, config, init: str | None, overrides: list) -> None:
    """Refuse ``data`` of another dataset than the config's ``dataset`` (:func:`hcmt.config.check_same_dataset`),
    naming the config as given (``config``: its file or name, and the base that set ``dataset``; a fine-tuned
    run's source when None)."""
    meta = read_meta(data)
    if meta.get("dataset") in (None, cfg.dataset):
        return
    origin = None
    if isinstance(config, (str, os.PathLike)):
        source = f"config {config}"
        if any(str(o).startswith("dataset=") for o in overrides):
            origin = "an override"
        else:
            base = set_in(config, "dataset")
            origin = None if base in (None, str(config), Path(str(config)).stem) else f"its base {base}"
    else:
        source = f"config of {init}" if config is None and init is not None else "config"
    check_same_dataset(cfg.dataset, meta, data, source, origin)


def start_record(
    folder: RunFolder,
    args: dict,
    cfg: Config,
    data,
    seed: int,
    world: int,
    *,
    resume: bool,
    init: str | None,
    init_normalizers: str,
) -> tuple[dict, Run | None]:
    """``run.yaml``'s record of this run and the :class:`Run` it starts from (``init``; None when resuming: the
    checkpoint holds the weights already), every start rule checked (the run folder's first:
    :func:`~hcmt.data.runs.check_start`)."""
    if resume or folder.latest.is_file():  # train() has cleared or refused a folder holding only run.yaml
        check_start(folder, resume, flags=True)
    if init_normalizers not in INIT_NORMALIZERS:
        raise InputError(f"init_normalizers must be one of {', '.join(INIT_NORMALIZERS)}, got {init_normalizers!r}")
    if resume and init is not None:
        raise InputError(
            "starts a run from another model's weights and resuming continues a run (whose "
            "run.yaml remembers where it started); give one of them",
            param="init",
        )
    run = {"model": args, "config": cfg, "data": str(Path(data).resolve()), "seed": seed, "world_size": world}
    source, started_from = None, None
    if resume and folder.info is not None:
        started_from = folder.info.get("init")
    elif init is not None:
        source = init_source(init, args)  # refused before anything is written
        started_from = {"from": source.source, "normalizers": init_normalizers, "step": int(source.checkpoint_step)}
    if started_from:
        run["init"] = started_from
    if resume and folder.info is not None:
        check_resume(folder.info, run, folder.path)
    return run, source


def resume_state(folder: RunFolder, model, opt, device, steps: int, rank: int) -> tuple[int, float, list | None]:
    """Load the latest checkpoint of ``folder`` into ``model`` and ``opt``: (its step, its best validation score,
    the log records up to that step on rank 0, read and checked here, else None). A checkpoint that does not fit
    the model or optimizer, or a run with more steps done than ``train.steps``, is refused in one line."""
    path = folder.latest
    state = read_checkpoint(path, device, earlier=folder.best)
    try:
        model.load_state_dict(state["model"])
        opt.load_state_dict(state["optimizer"])
    except (KeyError, RuntimeError, ValueError) as exc:
        raise InputError(
            f"{path}: the checkpoint does not fit this run's model or optimizer "
            f"({exc.__class__.__name__}); resuming continues only the run that wrote it"
        ) from None
    step, best = int(state["step"]), float(state["best"])
    if step > steps:
        raise InputError(
            f"{folder.path}: train.steps {steps}, but the run has done {step} steps; a "
            "run only grows (train.steps, --steps in hcmt train, >= the steps done)"
        )
    kept = [r for r in folder.log_records() if r["step"] <= step] if rank == 0 and folder.log.is_file() else None
    return step, best, kept


def write_start(folder: RunFolder, run: dict, data, kept_log: list | None) -> None:
    """The run folder written once every check passed: ``run.yaml`` (``run``), the data's facts and, resuming, the
    log records up to the checkpoint's step (``kept_log``, :func:`resume_state`)."""
    folder.path.mkdir(parents=True, exist_ok=True)
    folder.write_info(run)
    folder.write_data_facts(data)
    if kept_log is not None:
        rewrite_log(folder.log, kept_log)  # what was logged after the checkpoint goes
