"""hcmt: learned simulation of flexible bodies in contact (Hierarchical Contact Mesh Transformer).

The Python API (imported lazily, so ``import hcmt`` and ``hcmt --help`` stay fast):

* :class:`hcmt.Run` (``Run.load(path_or_"pretrained:NAME", device=None)``): a trained model, its config and data facts;
* :func:`hcmt.load_pretrained` (``NAME``): a model shipped inside the package, offline;
* :func:`hcmt.predict_designs`: peak stress and deflection of Impact Plate designs, no solver run, with the run's
  response surface beside the model (the design check of ``hcmt predict``);
* :class:`hcmt.Surrogate`: a Gaussian-process response surface on the design parameters (``Surrogate.fit_dataset``,
  ``save``, ``load``);
* :class:`hcmt.Design`: the parameters of one Impact Plate design; :func:`hcmt.design_for` (``run, **params``): one
  over the middle of a model's training ranges;
* :func:`hcmt.evaluate` (``run, data, split``): the paper's metrics and the physics metrics of a run on a split;
* :func:`hcmt.load_dataset` (a native dataset folder), :func:`hcmt.train` (``config, data, model, out, **options``;
  ``init=`` fine-tunes from another model), :class:`hcmt.FrameDataset` (training frames for a ``DataLoader``),
  :func:`hcmt.load_config` (a frozen :class:`hcmt.Config`: ``cfg.train.lr``);
* the models :class:`hcmt.HCMT`, :class:`hcmt.MGN`, :class:`hcmt.GT` (constructor arguments and shapes in their
  docstrings), :func:`hcmt.build_model` (``name, node_in, mesh_in, contact_in, out, **args``) and
  :func:`hcmt.from_checkpoint`.

The package's layers import only downward (tests/test_layers.py): ``errors`` → ``config`` → ``data`` → ``sim``,
``graph`` → ``models`` → ``domains`` → ``inference`` → ``training``, ``viz`` → ``design`` → ``cli``. This module
stands above them all and imports on first use (PEP 562 ``__getattr__``), so ``import hcmt`` stays fast.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from hcmt.config import VERSION as __version__

if TYPE_CHECKING:  # what IDEs and type checkers see; at run time each name loads on first use (_LAZY)
    from hcmt.config import Config, load_config
    from hcmt.data.format import load_dataset
    from hcmt.data.runs import available_pretrained
    from hcmt.design.check import predict_designs
    from hcmt.design.inputs import design_for
    from hcmt.design.surrogate import Surrogate
    from hcmt.inference.evaluate import evaluate
    from hcmt.inference.run import Run
    from hcmt.models import GT, HCMT, MGN, build_model, from_checkpoint
    from hcmt.sim.generate import generate_dataset
    from hcmt.sim.params import Design, Settings
    from hcmt.training import train
    from hcmt.training.dataset import FrameDataset

_LAZY = {
    "Run": ("hcmt.inference.run", "Run"),
    "available_pretrained": ("hcmt.data.runs", "available_pretrained"),
    "evaluate": ("hcmt.inference.evaluate", "evaluate"),
    "train": ("hcmt.training", "train"),
    "Design": ("hcmt.sim.params", "Design"),
    "Settings": ("hcmt.sim.params", "Settings"),
    "generate_dataset": ("hcmt.sim.generate", "generate_dataset"),
    "predict_designs": ("hcmt.design.check", "predict_designs"),
    "design_for": ("hcmt.design.inputs", "design_for"),
    "Surrogate": ("hcmt.design.surrogate", "Surrogate"),
    "load_dataset": ("hcmt.data.format", "load_dataset"),
    "FrameDataset": ("hcmt.training.dataset", "FrameDataset"),
    "load_config": ("hcmt.config", "load_config"),
    "Config": ("hcmt.config", "Config"),
    "HCMT": ("hcmt.models", "HCMT"),
    "MGN": ("hcmt.models", "MGN"),
    "GT": ("hcmt.models", "GT"),
    "build_model": ("hcmt.models", "build_model"),
    "from_checkpoint": ("hcmt.models", "from_checkpoint"),
}


def load_pretrained(name: str, device: str | None = None) -> Run:
    """The shipped model ``name`` (e.g. ``impact_plate_small``; ``pretrained:impact_plate_small`` too) as a
    :class:`hcmt.Run`; ``hcmt models`` lists them. Loaded from the package, never downloaded."""
    if not isinstance(name, str) or not name.strip():
        from hcmt.errors import InputError, clip
        from hcmt.sim.params import a_type

        raise InputError(
            f"expected a shipped model's name as text, e.g. 'impact_plate_small' (`hcmt models` lists "
            f"them), got {clip(repr(name))} ({a_type(name)})",
            param="name",
        )
    name = name.strip().removeprefix("pretrained:")
    return __getattr__("Run").load(f"pretrained:{name}", device)


def __getattr__(name):
    if name in _LAZY:
        module, attr = _LAZY[name]
        return getattr(importlib.import_module(module), attr)
    raise AttributeError(f"module 'hcmt' has no attribute {name!r}")


__all__ = [
    "Config",
    "GT",
    "HCMT",
    "MGN",
    "Design",
    "FrameDataset",
    "Run",
    "Settings",
    "Surrogate",
    "__version__",
    "available_pretrained",
    "build_model",
    "design_for",
    "evaluate",
    "from_checkpoint",
    "generate_dataset",
    "load_config",
    "load_dataset",
    "load_pretrained",
    "predict_designs",
    "train",
]
