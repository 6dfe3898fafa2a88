"""Training: the frames of a split as a ``Dataset`` (:mod:`~hcmt.training.dataset`), the loop
(:mod:`~hcmt.training.trainer`), its schedule and its process plumbing (:mod:`~hcmt.training.runtime`), and
:func:`train`, the API entry (``hcmt.train``)."""
from __future__ import annotations

import shutil
from pathlib import Path

from hcmt.config import load_config
from hcmt.training.trainer import train as run_training


def train(config, data, model: str, out, *, overrides=None, resume: bool = False, overwrite: bool = False,
          **options):
    """Train ``model`` (``hcmt``, ``mgn``, ``gt``) on the native dataset ``data`` into the run folder ``out``.
    ``config`` is a config dict, a built-in config name or a YAML path; ``overrides`` a list of
    ``section.key=value``; ``resume=True`` continues the run in ``out``, ``overwrite=True`` deletes it and starts
    afresh (otherwise a folder holding a run is refused); ``options``: ``ablation``, ``seed``, ``device``,
    ``progress``. Returns the training summary; :meth:`hcmt.Run.load` (``out``) gives the trained model."""
    if resume and overwrite:
        raise ValueError("hcmt.train: resume=True and overwrite=True contradict each other; choose one")
    out = Path(out)
    held = (out / "checkpoint.pt").is_file() or (out / "run.yaml").is_file()
    if held and not resume:
        if not overwrite:
            raise ValueError(f"hcmt.train: {out} already holds a run; pass resume=True to continue it, "
                             "overwrite=True to delete it and start afresh, or another out folder")
        shutil.rmtree(out)
    cfg = config if isinstance(config, dict) else load_config(str(config), overrides)
    return run_training(cfg, data, model, out, resume=resume, **options)


__all__ = ["train"]
