"""hcmt: learned simulation of flexible bodies in contact (Hierarchical Contact Mesh Transformer).

The Python API (imported lazily, so ``import hcmt`` and ``hcmt --help`` stay fast):

* :class:`hcmt.Run` (``Run.load(path_or_"pretrained:NAME", device=None)``): a trained model, its config and data facts;
* :func:`hcmt.load_pretrained` (``NAME``): a model shipped inside the package, offline;
* :func:`hcmt.predict_designs`: peak stress and deflection of Impact Plate designs, no solver run;
* :class:`hcmt.Design`: the parameters of one Impact Plate design;
* :func:`hcmt.load_dataset` (a native dataset folder), :func:`hcmt.train` (``config, data, model, out, **options``),
  :class:`hcmt.FrameDataset` (training frames for a ``DataLoader``), :func:`hcmt.load_config`.
"""

__version__ = "0.1.0"

_LAZY = {
    "Run": ("hcmt.train.run", "Run"),
    "available_pretrained": ("hcmt.train.run", "available_pretrained"),
    "Design": ("hcmt.sim.scene", "Design"),
    "Settings": ("hcmt.sim.scene", "Settings"),
    "generate_dataset": ("hcmt.sim.generate", "generate_dataset"),
    "predict_designs": ("hcmt.train.predict", "predict"),
    "load_dataset": ("hcmt.data.format", "load_dataset"),
    "FrameDataset": ("hcmt.train.frames", "FrameDataset"),
    "load_config": ("hcmt.train.config", "load_config"),
}


def load_pretrained(name: str, device: str | None = None):
    """The shipped model ``name`` (e.g. ``impact_plate_small``) as a :class:`hcmt.Run`; ``hcmt models`` lists
    them. Loaded from the package, never downloaded."""
    from hcmt.train.run import Run

    return Run.load(f"pretrained:{name}", device)


def __getattr__(name):
    if name == "train":  # the subpackage hcmt.train, callable as hcmt.train(config, data, model, out, ...)
        import importlib

        return importlib.import_module("hcmt.train")
    if name in _LAZY:
        import importlib

        module, attr = _LAZY[name]
        return getattr(importlib.import_module(module), attr)
    raise AttributeError(f"module 'hcmt' has no attribute {name!r}")


__all__ = ["Design", "FrameDataset", "Run", "Settings", "__version__", "available_pretrained", "generate_dataset",
           "load_config", "load_dataset", "load_pretrained", "predict_designs", "train"]
