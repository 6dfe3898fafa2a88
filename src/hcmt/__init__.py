"""hcmt: learned simulation of flexible bodies in contact (Hierarchical Contact Mesh Transformer).

The Python API (imported lazily, so ``import hcmt`` and ``hcmt --help`` stay fast):

* :class:`hcmt.Run` (``Run.load(path_or_"pretrained:NAME", device=None)``): a trained model, its config and data facts;
* :func:`hcmt.load_pretrained` (``NAME``): a model shipped inside the package, offline;
* :func:`hcmt.predict_designs`: peak stress and deflection of Impact Plate designs, no solver run, with the run's
  response surface beside the model (the design check of ``hcmt predict``);
* :class:`hcmt.Surrogate`: a Gaussian-process response surface on the design parameters (``Surrogate.fit_dataset``,
  ``save``, ``load``);
* :class:`hcmt.Design`: the parameters of one Impact Plate design;
* :func:`hcmt.evaluate` (``run, data, split``): the paper's metrics and the physics metrics of a run on a split;
* :func:`hcmt.load_dataset` (a native dataset folder), :func:`hcmt.train` (``config, data, model, out, **options``),
  :class:`hcmt.FrameDataset` (training frames for a ``DataLoader``), :func:`hcmt.load_config`.

The package's layers import only downward (tests/test_layers.py): ``config`` → ``data`` → ``sim``, ``graph`` →
``models`` → ``physics`` → ``inference`` → ``training``, ``viz`` → ``design`` → ``cli``. This module stands above
them all and imports on first use (PEP 562 ``__getattr__``), so ``import hcmt`` stays fast.
"""

import importlib

from hcmt.config import VERSION as __version__

_LAZY = {
    "Run": ("hcmt.inference.run", "Run"),
    "available_pretrained": ("hcmt.inference.run", "available_pretrained"),
    "evaluate": ("hcmt.inference.evaluate", "evaluate"),
    "train": ("hcmt.training", "train"),
    "Design": ("hcmt.sim.scene", "Design"),
    "Settings": ("hcmt.sim.scene", "Settings"),
    "generate_dataset": ("hcmt.sim.generate", "generate_dataset"),
    "predict_designs": ("hcmt.design.predict", "predict_designs"),
    "Surrogate": ("hcmt.design.surrogate", "Surrogate"),
    "load_dataset": ("hcmt.data.format", "load_dataset"),
    "FrameDataset": ("hcmt.training.dataset", "FrameDataset"),
    "load_config": ("hcmt.config", "load_config"),
}


def load_pretrained(name: str, device: str | None = None):
    """The shipped model ``name`` (e.g. ``impact_plate_small``) as a :class:`hcmt.Run`; ``hcmt models`` lists
    them. Loaded from the package, never downloaded."""
    return __getattr__("Run").load(f"pretrained:{name}", device)


def __getattr__(name):
    if name in _LAZY:
        module, attr = _LAZY[name]
        return getattr(importlib.import_module(module), attr)
    raise AttributeError(f"module 'hcmt' has no attribute {name!r}")


__all__ = ["Design", "FrameDataset", "Run", "Settings", "Surrogate", "__version__", "available_pretrained", "evaluate", "generate_dataset",
           "load_config", "load_dataset", "load_pretrained", "predict_designs", "train"]
