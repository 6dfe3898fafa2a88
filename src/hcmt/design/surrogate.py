"""A response surface on the design parameters: what an engineer fits on a family's solver runs instead of a mesh model.

:class:`Surrogate` is one Gaussian process per scalar answer of a design (scikit-learn's
:class:`~sklearn.gaussian_process.GaussianProcessRegressor`; hcmt does not write its own GP), on log inputs and
log outputs, each standardized over the training designs:

    z = (log x − m_x) / s_x,      y = (log q − m_q) / s_q,
    k(z, z') = c² exp(−½ Σ_d (z_d − z'_d)² / ℓ_d²) + σ_n² δ(z, z')      (ARD RBF + white noise)

Its 95 % interval is ``exp(m_q + s_q (μ ± 1.96 σ))`` with the predictive σ of the white-noise-including kernel, so
a design's answer is a central estimate and a band that is not symmetric in MPa. Inputs are the parameters that
vary over the training designs (a parameter held fixed there is recorded with its value: the surrogate cannot learn
what it never saw vary). The answers (:data:`QUANTITIES`) are those of :func:`hcmt.design.readout.summarize_fields`
on the solver's trajectories: peak plate and ball stress, maximum deflection, the time the plate first reaches 95 % of
its peak and the time the ball leaves the plate (which bounds the mesh model's contact window:
:func:`hcmt.design.readout.summarize_fields`).

Stored without pickle (:meth:`Surrogate.save`, :meth:`Surrogate.load`; the format: :mod:`hcmt.design.surrogate_file`):
loading refits the posterior with the stored hyperparameters (no optimizer run), so a loaded surrogate predicts what
the fitted one did, to rounding. The process itself is :mod:`hcmt.design.gp`; the training data and what a surrogate
records of it, :mod:`hcmt.design.surrogate_data`.
A surrogate meets a model in :func:`hcmt.design.surrogate_use.for_run`: one that does not fit it
(:meth:`Surrogate.check_model`) is refused, and one whose window is not known to be the model's never ends the model's
read-out window.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from hcmt.config import plural
from hcmt.data.format import read_meta
from hcmt.design.basics import QUANTITIES, RESTARTS  # noqa: F401 (QUANTITIES: hcmt.design.surrogate.QUANTITIES)
from hcmt.design.gp import Z95, fit_gp, intervals  # noqa: F401 (Z95: re-exported)
from hcmt.design.summary import SurrogateAnswer
from hcmt.design.surrogate_data import (  # noqa: F401 (re-exported: hcmt.design.surrogate.dataset_facts, ...)
    ANSWER_UNITS,
    SurrogateError,
    data_differences,
    dataset_answers,
    dataset_facts,
    range_differences,
)
from hcmt.design.surrogate_file import FORMAT, READS, VERSION, document, parse_document, read_document  # noqa: F401
from hcmt.errors import InputError
from hcmt.files import atomic_path
from hcmt.sim.params import DESIGN_KEYS, Design


class Surrogate:
    """Gaussian-process response surfaces of a design family's scalar answers, fitted on its solver runs.

    Args:
        parameters: the design parameters the surfaces take (those that vary over the training designs).
        fixed: the parameters held fixed over the training designs, with their values.
        X: [n, d] the training designs' parameters (in ``parameters``' order).
        Y: answer name -> [n] the solver's answer of each training design.
        kernels: answer name -> ``{"constant", "length_scales" [d], "noise"}``: the fitted hyperparameters
            (None: fit them by maximizing the marginal likelihood, ``restarts`` restarts, ``seed``).
        source: where the training designs came from (recorded in the file).
        dataset: what the training data was (:func:`dataset_facts`; None: not known, as in a version 1 file).
    """

    def __init__(
        self,
        parameters: list[str],
        fixed: dict[str, float],
        X,
        Y: dict[str, np.ndarray],
        kernels: dict | None = None,
        *,
        source: str = "",
        restarts: int = RESTARTS,
        seed: int = 0,
        linear: list[str] | None = None,
        strict: bool = True,
        dataset: dict | None = None,
    ):
        self.parameters, self.fixed, self.source = list(parameters), dict(fixed), source
        self.name = ""  # what the header calls it (:attr:`label`): set by surrogate_use.for_run, never a path
        self.dataset = dict(dataset) if dataset is not None else None
        if not self.parameters:
            raise InputError("no design parameter varies over the training designs: nothing to fit")
        self.X = np.asarray(X, np.float64).reshape(-1, len(self.parameters))
        self.Y = {q: np.asarray(v, np.float64) for q, v in Y.items()}
        n, d = self.X.shape
        self.underdetermined = n < d + 2  # allowed with strict=False (a benchmark's few runs of a new family)
        if n < 3 or (strict and self.underdetermined):
            raise InputError(
                f"{n} training designs for {d} parameters: a surrogate needs at least parameters + 2 ({d + 2}) designs"
            )
        # log inputs, but a parameter that is 0 in some design (an absent layer, support, pen) stays linear
        self.linear = (
            [k for j, k in enumerate(self.parameters) if np.any(self.X[:, j] <= 0)] if linear is None else list(linear)
        )
        self._log = np.array([k not in self.linear for k in self.parameters])
        if not (np.all(np.isfinite(self.X)) and np.all(self.X[:, self._log] > 0) and np.all(self.X >= 0)):
            raise InputError(
                "training designs must be finite and non-negative, positive where the surrogate takes their log"
            )
        for q, v in self.Y.items():
            if v.shape != (n,) or not (np.all(np.isfinite(v)) and np.all(v > 0)):
                raise InputError(f"answer {q!r}: expected {n} finite positive values (log outputs)")
        logx = self._x(self.X)
        self.x_mean, self.x_std = logx.mean(0), np.maximum(logx.std(0), 1e-12)
        self.y_mean = {q: float(np.log(v).mean()) for q, v in self.Y.items()}
        self.y_std = {q: float(max(np.log(v).std(), 1e-12)) for q, v in self.Y.items()}
        self.kernels: dict = {}
        self._gps = {}
        z = self._z(self.X)
        for q, v in self.Y.items():
            y = (np.log(v) - self.y_mean[q]) / self.y_std[q]
            self._gps[q], self.kernels[q] = fit_gp(z, y, (kernels or {}).get(q), restarts, seed)

    # -- fitting ---------------------------------------------------------------------------------------------------
    @classmethod
    def fit_dataset(
        cls,
        data: str | Path,
        split: str = "train",
        *,
        limit: int | None = None,
        restarts: int = RESTARTS,
        seed: int = 0,
        stress_field: str = "stress",
    ) -> "Surrogate":
        """Fit on the solver trajectories of an hcmt-generated Impact Plate dataset's ``split`` (the first
        ``limit`` when given): :func:`dataset_answers`."""
        designs, answers = dataset_answers(data, split, limit, stress_field)
        s = cls.fit(
            designs,
            answers,
            source=f"{Path(data)} ({split}, {len(designs)} trajectories)",
            restarts=restarts,
            seed=seed,
        )
        s.dataset = dataset_facts(read_meta(data), split, stress_field, answers)
        return s

    @classmethod
    def fit(
        cls,
        designs: list[Design],
        answers: dict[str, list[float]],
        *,
        source: str = "",
        restarts: int = RESTARTS,
        seed: int = 0,
        strict: bool = True,
    ) -> "Surrogate":
        """Fit on designs and their solver answers; the parameters that vary over ``designs`` are the inputs
        (``strict=False`` fits fewer designs than parameters + 2 too, at least 3: most length scales then stay
        at their bound and the surfaces predict near the mean)."""
        if not designs:
            raise InputError("no training designs")
        values = np.array([[getattr(d, k) for k in DESIGN_KEYS] for d in designs], np.float64)
        spread = values.max(0) - values.min(0) > 1e-9 * np.maximum(np.abs(values).max(0), 1e-300)
        params = [k for k, s in zip(DESIGN_KEYS, spread) if s]
        fixed = {k: float(values[0, j]) for j, (k, s) in enumerate(zip(DESIGN_KEYS, spread)) if not s}
        return cls(
            params, fixed, values[:, spread], answers, source=source, restarts=restarts, seed=seed, strict=strict
        )

    @property
    def censored(self) -> int:
        """How many training runs' window ended before the ball left (0 when not known)."""
        return int((self.dataset or {}).get("censored", 0))

    # -- predicting ------------------------------------------------------------------------------------------------
    def _x(self, X: np.ndarray) -> np.ndarray:
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(self._log, np.log(np.where(self._log, X, 1.0)), X)

    def _z(self, X: np.ndarray) -> np.ndarray:
        return (self._x(X) - self.x_mean) / self.x_std

    def cannot_take(self, design: Design) -> list[str]:
        """The parameters of ``design`` the surfaces cannot take at all: held fixed over every training design
        but different here (a layer, support or impactor the training family never had)."""
        default = Design()  # a surrogate fitted before the panel families: their parameters held at the default
        held = {
            **{k: getattr(default, k) for k in DESIGN_KEYS if k not in self.fixed and k not in self.parameters},
            **self.fixed,
        }
        return [k for k, v in held.items() if not np.isclose(getattr(design, k), v, rtol=1e-9, atol=1e-12)]

    def matrix(self, designs: list[Design]) -> np.ndarray:
        return np.array([[getattr(d, k) for k in self.parameters] for d in designs], np.float64).reshape(
            len(designs), len(self.parameters)
        )

    def predict(self, designs: list[Design]) -> list[dict[str, SurrogateAnswer]]:
        """Per design, each answer's :class:`~hcmt.design.summary.SurrogateAnswer` (central estimate and 95 %
        interval, in the answer's unit)."""
        if not designs:
            return []
        X = self.matrix(designs)
        if not np.all(X[:, self._log] > 0):
            raise InputError("design parameters must be positive for the surrogate (log inputs)")
        z = self._z(X)
        answers = {q: intervals(gp, z, self.y_mean[q], self.y_std[q]) for q, gp in self._gps.items()}
        return [{q: v[i] for q, v in answers.items()} for i in range(len(designs))]

    def ranges(self) -> dict[str, tuple[float, float]]:
        """Min and max of every design parameter over the training designs (fixed ones: their value twice)."""
        out = {k: (float(self.X[:, j].min()), float(self.X[:, j].max())) for j, k in enumerate(self.parameters)}
        out.update({k: (v, v) for k, v in self.fixed.items()})
        return out

    def __len__(self) -> int:
        return len(self.X)

    @property
    def label(self) -> str:
        """What a report's header calls this surface: its name (the model's own, or its file's name) and the count of
        runs it was fitted on, never a machine's path (:attr:`source`, the file's record, may hold the command and the
        folders that made it)."""
        runs = f"fitted on {plural(len(self), 'solver run')}"
        return f"{self.name}, {runs}" if self.name else f"a Gaussian process {runs}"

    def __repr__(self) -> str:
        return (
            f"Surrogate({len(self)} designs, parameters {self.parameters}, answers {list(self.Y)}"
            + (f", from {self.source}" if self.source else "")
            + ")"
        )

    # -- storing (the format: hcmt.design.surrogate_file) -------------------------------------------------------------
    def to_dict(self) -> dict:
        return document(self)

    def save(self, path: str | Path) -> Path:
        """Write the surrogate as JSON, atomically."""
        path = Path(path)
        with atomic_path(path) as tmp:
            tmp.write_text(json.dumps(self.to_dict(), indent=1))
        return path

    @classmethod
    def load(cls, path: str | Path) -> "Surrogate":
        """Read a surrogate written by :meth:`save` and refit its posterior with the stored hyperparameters (no
        optimizer run). A file that is missing, not JSON, truncated or inconsistent raises
        :class:`SurrogateError` naming it."""
        return cls.from_dict(read_document(Path(path)), where=str(path))

    @classmethod
    def from_dict(cls, doc, where: str = "surrogate") -> "Surrogate":
        return parse_document(doc, cls, where)

    # -- use against a model ---------------------------------------------------------------------------------------
    def check_parameters(self, ranges: dict[str, tuple[float, float]], where: str, param: str | None = None) -> None:
        """Refuse a surrogate whose parameters differ from the model's varied ones (``ranges``: the model's
        training ranges)."""
        varied = sorted(k for k, (lo, hi) in ranges.items() if k in DESIGN_KEYS and hi > lo)
        if varied and sorted(self.parameters) != varied:
            missing, extra = sorted(set(varied) - set(self.parameters)), sorted(set(self.parameters) - set(varied))
            differ = "; ".join(
                f"{w}: {', '.join(ks)}" for w, ks in (("not taken", missing), ("not varied by the model", extra)) if ks
            )
            raise SurrogateError(
                f"{where}: the surrogate takes other parameters than the model's training designs "
                f"vary ({differ}); fit it on the model's own data (`hcmt surrogate fit`)",
                param=param,
            )

    def check_model(
        self,
        ranges: dict[str, tuple[float, float]],
        meta: dict | None,
        stress_field: str,
        where: str,
        param: str | None = None,
    ) -> None:
        """Refuse, in one line naming ``where`` and what differs, a surrogate that does not fit the model: other
        parameters, training ranges that do not cover the model's, a parameter held at another value, and (when
        the file records its data, format 2) another frame window or interval, stress field, family or unit."""
        self.check_parameters(ranges, where, param)
        differ = data_differences(self.dataset, meta, stress_field) if self.dataset is not None and meta else []
        narrow = range_differences(self.ranges(), ranges)
        if narrow:
            others = [n.split(" ", 1)[0] for n in narrow[1:]]
            differ.append(
                f"its training ranges do not cover the model's: {narrow[0]}"
                + (f" (also {', '.join(others[:2])}{', ...' if len(others) > 2 else ''})" if others else "")
            )
        if differ:
            more = f" (and {len(differ) - 1} more)" if len(differ) > 1 else ""
            raise SurrogateError(
                f"{where}: does not fit the model: {differ[0]}{more}; fit it on the model's own training data",
                param=param,
            )
