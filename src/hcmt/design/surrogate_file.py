"""The response surface's file format, JSON without pickle: :func:`document` (what
:meth:`hcmt.design.surrogate.Surrogate.save` writes: the kernel's hyperparameters, the training designs and their
solver answers, the transforms) and :func:`read_document` / :func:`parse_document` (what ``load`` reads back,
every part checked, a bad file refused in one line naming it). Version 2 adds ``dataset``
(:func:`hcmt.design.surrogate_data.dataset_facts`); version 1 files (no ``dataset``) still load."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from hcmt.design.surrogate_data import SurrogateError, read_facts
from hcmt.errors import InputError, clip
from hcmt.sim.cost import check_size
from hcmt.sim.params import DESIGN_KEYS, Design

FORMAT, VERSION = "hcmt-surrogate", 2
READS = (1, 2)  # the format versions this hcmt loads (1: no "dataset" block)


def document(s) -> dict:
    """A :class:`~hcmt.design.surrogate.Surrogate` as the file's JSON document."""
    return {
        "format": FORMAT,
        "version": VERSION,
        "source": s.source,
        **({"dataset": s.dataset} if s.dataset is not None else {}),
        "model": "GaussianProcessRegressor: ConstantKernel * RBF(ARD) + WhiteKernel on standardized log "
        "inputs and log outputs; 95 % interval = exp(m + s (mu +- 1.96 sd))",
        "parameters": s.parameters,
        "fixed": s.fixed,
        "input_transform": {
            "kind": "log-standardize",
            "mean": s.x_mean.tolist(),
            "std": s.x_std.tolist(),
            "linear": s.linear,
        },
        "output_transform": {q: {"kind": "log-standardize", "mean": s.y_mean[q], "std": s.y_std[q]} for q in s.Y},
        "kernels": s.kernels,
        "designs": s.X.tolist(),
        "answers": {q: v.tolist() for q, v in s.Y.items()},
    }


def read_document(path: Path):
    """The JSON document of a surrogate file; :class:`SurrogateError` naming it when it is missing or no JSON."""
    if not path.is_file():
        raise SurrogateError(
            f"{path}: no such surrogate file (make one with `hcmt surrogate fit DATA --out {path.name}`)"
        )
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise SurrogateError(
            f"{path}: not a surrogate JSON file (truncated or corrupt?): "
            f"{str(exc).splitlines()[0][:200] if str(exc) else exc.__class__.__name__}"
        ) from None


def parse_document(doc, build, where: str = "surrogate"):
    """``build`` (the :class:`~hcmt.design.surrogate.Surrogate` constructor) called with a document's parts, every
    part checked and the build's own refusal (too few designs, ...) included: :class:`SurrogateError` naming
    ``where`` and what is wrong."""
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise SurrogateError(f'{where}: not an hcmt surrogate (expected "format": "{FORMAT}")')
    if doc.get("version") not in READS:
        raise SurrogateError(
            f"{where}: surrogate format version {doc.get('version')!r}, this hcmt reads {' and '.join(map(str, READS))}"
        )
    try:
        params, fixed, designs = list(doc["parameters"]), dict(doc["fixed"]), doc["designs"]
        answers, kernels = dict(doc["answers"]), dict(doc["kernels"])
        unknown = [k for k in [*params, *fixed] if k not in DESIGN_KEYS]
        if unknown:
            raise SurrogateError(
                f"{where}: unknown design parameters {unknown}; expected some of {', '.join(DESIGN_KEYS)}"
            )
        X = np.asarray(designs, np.float64)
        if X.ndim != 2 or X.shape[1] != len(params):
            raise SurrogateError(f'{where}: "designs" must be a table of {len(params)} columns (the parameters)')
        _check_kernels(kernels, answers, len(params), where)
        transform = doc.get("input_transform") or {}
        linear = transform.get("linear") or [] if isinstance(transform, dict) else None
        if not isinstance(linear, list) or any(k not in params for k in linear):
            raise SurrogateError(f'{where}: "input_transform": expected {{"linear": [parameters taken linearly]}}}}')
        for i, row in enumerate(X):  # each training design one hcmt could build (a 1e308 mm plate is none)
            try:
                check_size(Design(**{**fixed, **dict(zip(params, map(float, row)))}).validate())
            except InputError as exc:
                raise SurrogateError(
                    f"{where}: training design {i + 1} is no design hcmt builds: {clip(exc, 160)}"
                ) from None
        return build(
            params,
            {k: float(v) for k, v in fixed.items()},
            X,
            answers,
            kernels,
            source=str(doc.get("source", "")),
            linear=linear,
            dataset=read_facts(doc["dataset"], where) if "dataset" in doc else None,
        )
    except SurrogateError:
        raise
    except (KeyError, TypeError, ValueError, OverflowError) as exc:
        what = f"missing key {exc}" if isinstance(exc, KeyError) else str(exc).splitlines()[0][:200]
        raise SurrogateError(f"{where}: not a usable surrogate: {what}") from None


def _check_kernels(kernels: dict, answers: dict, d: int, where: str) -> None:
    """Each answer's stored kernel: a positive constant and noise and ``d`` positive length scales."""
    for q, k in kernels.items():
        ls = np.asarray(k["length_scales"], np.float64)
        if (
            ls.shape != (d,)
            or not all(np.isfinite(float(k[h])) and 0 < float(k[h]) <= 1e6 for h in ("constant", "noise"))
            or not np.all(np.isfinite(ls) & (ls > 0))
        ):
            raise SurrogateError(f"{where}: kernel of {q!r}: expected positive constant, noise and {d} length scales")
    if set(kernels) != set(answers):
        raise SurrogateError(f"{where}: kernels for {sorted(kernels)} but answers for {sorted(answers)}")
