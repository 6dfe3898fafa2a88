"""A response surface on the design parameters: what an engineer fits on a family's solver runs instead of a mesh model.

:class:`Surrogate` is one Gaussian process per scalar answer of a design (scikit-learn's
:class:`~sklearn.gaussian_process.GaussianProcessRegressor`; hcmt does not write its own GP), on log inputs and
log outputs, each standardized over the training designs:

    z = (log x − m_x) / s_x,      y = (log q − m_q) / s_q,
    k(z, z') = c² exp(−½ Σ_d (z_d − z'_d)² / ℓ_d²) + σ_n² δ(z, z')      (ARD RBF + white noise)

Its 95 % interval is ``exp(m_q + s_q (μ ± 1.96 σ))`` with the predictive σ of the white-noise-including kernel, so
a design's answer is a central estimate and a band that is not symmetric in MPa. Inputs are the parameters that
vary over the training designs (a parameter held fixed there is recorded with its value: the surrogate cannot learn
what it never saw vary). The answers (:data:`QUANTITIES`) are those of :func:`hcmt.design.readout.summarize` on the
solver's trajectories: peak plate and ball stress, maximum deflection, the time the plate first reaches 95 % of
its peak and the time the ball leaves the plate (which bounds the mesh model's contact window:
:func:`hcmt.design.readout.summarize_fields`).

Stored without pickle (:meth:`Surrogate.save`, :meth:`Surrogate.load`): JSON with the kernel's hyperparameters,
the training designs and their solver answers, and the transforms; loading refits the posterior with the stored
hyperparameters (``optimizer=None``), so a loaded surrogate predicts what the fitted one did, to rounding. Format
version 2 adds ``dataset`` (:func:`dataset_facts`: the training data's frame window and interval, families, stress
field, units and how many runs the window ended before the ball left); version 1 files (no ``dataset``) still load.
A surrogate meets a model in :func:`for_run`: one that does not fit it (:meth:`Surrogate.check_model`) is refused,
and one whose window is not known to be the model's never ends the model's read-out window.
"""
from __future__ import annotations

import json
import math
import warnings
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from sklearn.exceptions import ConvergenceWarning
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel

from hcmt.config import plural
from hcmt.data.format import Split, read_meta
from hcmt.data.runs import PRETRAINED_DIR
from hcmt.design.basics import QUANTITIES, RESTARTS
from hcmt.design.readout import summarize_fields
from hcmt.errors import InputError, clip
from hcmt.files import atomic_path
from hcmt.sim.cost import check_size
from hcmt.sim.params import DESIGN_KEYS, DESIGN_UNITS, FIRST_SCENE_KEYS, Design, design_from_attrs

FORMAT, VERSION = "hcmt-surrogate", 2
READS = (1, 2)  # the format versions this hcmt loads (1: no "dataset" block)
#: the unit of each answer (:data:`hcmt.design.basics.QUANTITIES`)
ANSWER_UNITS = {"peak_plate_stress_mpa": "MPa", "peak_ball_stress_mpa": "MPa", "max_deflection_mm": "mm",
                "peak_plate_t95_ms": "ms", "contact_end_ms": "ms"}
Z95 = 1.959963984540054  # the standard normal's 97.5 % quantile: a central 95 % interval


class SurrogateError(InputError):
    """A surrogate file that cannot be used; the message names the file and what is wrong."""


@dataclass
class Interval:
    """A surrogate's answer: central estimate and the central 95 % interval."""

    mean: float
    lo: float
    hi: float

    def covers(self, value: float) -> bool:
        return self.lo <= value <= self.hi


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

    def __init__(self, parameters: list[str], fixed: dict[str, float], X, Y: dict[str, np.ndarray],
                 kernels: dict | None = None, *, source: str = "", restarts: int = RESTARTS, seed: int = 0,
                 linear: list[str] | None = None, strict: bool = True, dataset: dict | None = None):
        self.parameters, self.fixed, self.source = list(parameters), dict(fixed), source
        self.name = ""  # what the header calls it (:attr:`label`): set by :func:`for_run`, never a path
        self.dataset = dict(dataset) if dataset is not None else None
        if not self.parameters:
            raise InputError("no design parameter varies over the training designs: nothing to fit")
        self.X = np.asarray(X, np.float64).reshape(-1, len(self.parameters))
        self.Y = {q: np.asarray(v, np.float64) for q, v in Y.items()}
        n, d = self.X.shape
        self.underdetermined = n < d + 2  # allowed with strict=False (a benchmark's few runs of a new family)
        if n < 3 or (strict and self.underdetermined):
            raise InputError(f"{n} training designs for {d} parameters: a surrogate needs at least parameters + 2 "
                             f"({d + 2}) designs")
        # log inputs, but a parameter that is 0 in some design (an absent layer, support, pen) stays linear
        self.linear = [k for j, k in enumerate(self.parameters) if np.any(self.X[:, j] <= 0)] if linear is None \
            else list(linear)
        self._log = np.array([k not in self.linear for k in self.parameters])
        if not (np.all(np.isfinite(self.X)) and np.all(self.X[:, self._log] > 0) and np.all(self.X >= 0)):
            raise InputError("training designs must be finite and non-negative, positive where the surrogate takes "
                             "their log")
        for q, v in self.Y.items():
            if v.shape != (n,) or not (np.all(np.isfinite(v)) and np.all(v > 0)):
                raise InputError(f"answer {q!r}: expected {n} finite positive values (log outputs)")
        logx = self._x(self.X)
        self.x_mean, self.x_std = logx.mean(0), np.maximum(logx.std(0), 1e-12)
        self.y_mean = {q: float(np.log(v).mean()) for q, v in self.Y.items()}
        self.y_std = {q: float(max(np.log(v).std(), 1e-12)) for q, v in self.Y.items()}
        self.kernels: dict = {}
        self._gps: dict[str, GaussianProcessRegressor] = {}
        z = self._z(self.X)
        for q, v in self.Y.items():
            y = (np.log(v) - self.y_mean[q]) / self.y_std[q]
            hyper = (kernels or {}).get(q)
            if hyper is None:
                gp = GaussianProcessRegressor(_kernel(d), n_restarts_optimizer=restarts, random_state=seed)
            else:
                gp = GaussianProcessRegressor(_kernel(d, hyper), optimizer=None)
            with warnings.catch_warnings():  # a length scale at its upper bound: that parameter does not matter
                warnings.simplefilter("ignore", ConvergenceWarning)
                gp.fit(z, y)
            self._gps[q] = gp
            self.kernels[q] = hyper or _hyper(gp.kernel_)

    # -- fitting ---------------------------------------------------------------------------------------------------
    @classmethod
    def fit_dataset(cls, data: str | Path, split: str = "train", *, limit: int | None = None,
                    restarts: int = RESTARTS, seed: int = 0, stress_field: str = "stress") -> "Surrogate":
        """Fit on the solver trajectories of an hcmt-generated Impact Plate dataset's ``split`` (the first
        ``limit`` when given): :func:`dataset_answers`."""
        designs, answers = dataset_answers(data, split, limit, stress_field)
        s = cls.fit(designs, answers, source=f"{Path(data)} ({split}, {len(designs)} trajectories)",
                    restarts=restarts, seed=seed)
        s.dataset = dataset_facts(read_meta(data), split, stress_field, answers)
        return s

    @classmethod
    def fit(cls, designs: list[Design], answers: dict[str, list[float]], *, source: str = "",
            restarts: int = RESTARTS, seed: int = 0, strict: bool = True) -> "Surrogate":
        """Fit on designs and their solver answers; the parameters that vary over ``designs`` are the inputs
        (``strict=False`` fits fewer designs than parameters + 2 too, at least 3: most length scales then stay
        at their bound and the surfaces predict near the mean)."""
        if not designs:
            raise InputError("no training designs")
        values = np.array([[getattr(d, k) for k in DESIGN_KEYS] for d in designs], np.float64)
        spread = values.max(0) - values.min(0) > 1e-9 * np.maximum(np.abs(values).max(0), 1e-300)
        params = [k for k, s in zip(DESIGN_KEYS, spread) if s]
        fixed = {k: float(values[0, j]) for j, (k, s) in enumerate(zip(DESIGN_KEYS, spread)) if not s}
        return cls(params, fixed, values[:, spread], answers, source=source, restarts=restarts, seed=seed,
                   strict=strict)

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
        held = {**{k: getattr(default, k) for k in DESIGN_KEYS if k not in self.fixed and k not in self.parameters},
                **self.fixed}
        return [k for k, v in held.items() if not np.isclose(getattr(design, k), v, rtol=1e-9, atol=1e-12)]

    def matrix(self, designs: list[Design]) -> np.ndarray:
        return np.array([[getattr(d, k) for k in self.parameters] for d in designs], np.float64).reshape(
            len(designs), len(self.parameters))

    def predict(self, designs: list[Design]) -> list[dict[str, Interval]]:
        """Per design, each answer's :class:`Interval` (central estimate and 95 % interval, in the answer's unit)."""
        if not designs:
            return []
        X = self.matrix(designs)
        if not np.all(X[:, self._log] > 0):
            raise InputError("design parameters must be positive for the surrogate (log inputs)")
        z = self._z(X)
        out: list[dict[str, Interval]] = [{} for _ in designs]
        for q, gp in self._gps.items():
            mu, sd = gp.predict(z, return_std=True)
            m, s = self.y_mean[q], self.y_std[q]
            for i in range(len(designs)):
                out[i][q] = Interval(float(np.exp(m + s * mu[i])), float(np.exp(m + s * (mu[i] - Z95 * sd[i]))),
                                     float(np.exp(m + s * (mu[i] + Z95 * sd[i]))))
        return out

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
        return (f"Surrogate({len(self)} designs, parameters {self.parameters}, answers {list(self.Y)}"
                + (f", from {self.source}" if self.source else "") + ")")

    # -- storing ---------------------------------------------------------------------------------------------------
    def to_dict(self) -> dict:
        return {"format": FORMAT, "version": VERSION, "source": self.source,
                **({"dataset": self.dataset} if self.dataset is not None else {}),
                "model": "GaussianProcessRegressor: ConstantKernel * RBF(ARD) + WhiteKernel on standardized log "
                         "inputs and log outputs; 95 % interval = exp(m + s (mu +- 1.96 sd))",
                "parameters": self.parameters, "fixed": self.fixed,
                "input_transform": {"kind": "log-standardize", "mean": self.x_mean.tolist(),
                                    "std": self.x_std.tolist(), "linear": self.linear},
                "output_transform": {q: {"kind": "log-standardize", "mean": self.y_mean[q], "std": self.y_std[q]}
                                     for q in self.Y},
                "kernels": self.kernels,
                "designs": self.X.tolist(), "answers": {q: v.tolist() for q, v in self.Y.items()}}

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
        path = Path(path)
        if not path.is_file():
            raise SurrogateError(f"{path}: no such surrogate file (make one with `hcmt surrogate fit DATA --out "
                                 f"{path.name}`)")
        try:
            doc = json.loads(path.read_text(encoding="utf-8"))
        except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
            raise SurrogateError(f"{path}: not a surrogate JSON file (truncated or corrupt?): "
                                 f"{str(exc).splitlines()[0][:200] if str(exc) else exc.__class__.__name__}") from None
        return cls.from_dict(doc, where=str(path))

    @classmethod
    def from_dict(cls, doc, where: str = "surrogate") -> "Surrogate":
        if not isinstance(doc, dict) or doc.get("format") != FORMAT:
            raise SurrogateError(f"{where}: not an hcmt surrogate (expected \"format\": \"{FORMAT}\")")
        if doc.get("version") not in READS:
            raise SurrogateError(f"{where}: surrogate format version {doc.get('version')!r}, this hcmt reads "
                                 f"{' and '.join(map(str, READS))}")
        try:
            params, fixed, designs = list(doc["parameters"]), dict(doc["fixed"]), doc["designs"]
            answers, kernels = dict(doc["answers"]), dict(doc["kernels"])
            unknown = [k for k in [*params, *fixed] if k not in DESIGN_KEYS]
            if unknown:
                raise SurrogateError(f"{where}: unknown design parameters {unknown}; expected some of "
                                     f"{', '.join(DESIGN_KEYS)}")
            X = np.asarray(designs, np.float64)
            if X.ndim != 2 or X.shape[1] != len(params):
                raise SurrogateError(f"{where}: \"designs\" must be a table of {len(params)} columns (the "
                                     "parameters)")
            for q, k in kernels.items():
                ls = np.asarray(k["length_scales"], np.float64)
                if ls.shape != (len(params),) or not all(
                        np.isfinite(float(k[h])) and 0 < float(k[h]) <= 1e6 for h in ("constant", "noise")) \
                        or not np.all(np.isfinite(ls) & (ls > 0)):
                    raise SurrogateError(f"{where}: kernel of {q!r}: expected positive constant, noise and "
                                         f"{len(params)} length scales")
            if set(kernels) != set(answers):
                raise SurrogateError(f"{where}: kernels for {sorted(kernels)} but answers for {sorted(answers)}")
            transform = doc.get("input_transform") or {}
            linear = transform.get("linear") or [] if isinstance(transform, dict) else None
            if not isinstance(linear, list) or any(k not in params for k in linear):
                raise SurrogateError(f"{where}: \"input_transform\": expected {{\"linear\": [parameters taken "
                                     "linearly]}}")
            for i, row in enumerate(X):  # each training design one hcmt could build (a 1e308 mm plate is none)
                try:
                    check_size(Design(**{**fixed, **dict(zip(params, map(float, row)))}).validate())
                except InputError as exc:
                    raise SurrogateError(f"{where}: training design {i + 1} is no design hcmt builds: "
                                         f"{clip(exc, 160)}") from None
            return cls(params, {k: float(v) for k, v in fixed.items()}, X, answers, kernels,
                       source=str(doc.get("source", "")), linear=linear,
                       dataset=_read_facts(doc["dataset"], where) if "dataset" in doc else None)
        except SurrogateError:
            raise
        except (KeyError, TypeError, ValueError, OverflowError) as exc:
            what = f"missing key {exc}" if isinstance(exc, KeyError) else str(exc).splitlines()[0][:200]
            raise SurrogateError(f"{where}: not a usable surrogate: {what}") from None

    # -- use against a model ---------------------------------------------------------------------------------------
    def check_parameters(self, ranges: dict[str, tuple[float, float]], where: str, param: str | None = None) -> None:
        """Refuse a surrogate whose parameters differ from the model's varied ones (``ranges``: the model's
        training ranges)."""
        varied = sorted(k for k, (lo, hi) in ranges.items() if k in DESIGN_KEYS and hi > lo)
        if varied and sorted(self.parameters) != varied:
            missing, extra = sorted(set(varied) - set(self.parameters)), sorted(set(self.parameters) - set(varied))
            differ = "; ".join(f"{w}: {', '.join(ks)}" for w, ks in (("not taken", missing), ("not varied by the "
                               "model", extra)) if ks)
            raise SurrogateError(f"{where}: the surrogate takes other parameters than the model's training designs "
                                 f"vary ({differ}); fit it on the model's own data (`hcmt surrogate fit`)", param=param)

    def check_model(self, ranges: dict[str, tuple[float, float]], meta: dict | None, stress_field: str, where: str,
                    param: str | None = None) -> None:
        """Refuse, in one line naming ``where`` and what differs, a surrogate that does not fit the model: other
        parameters, training ranges that do not cover the model's, a parameter held at another value, and (when
        the file records its data, format 2) another frame window or interval, stress field, family or unit."""
        self.check_parameters(ranges, where, param)
        differ = _data_differences(self.dataset, meta, stress_field) if self.dataset is not None and meta else []
        narrow = self._range_differences(ranges)
        if narrow:
            others = [n.split(" ", 1)[0] for n in narrow[1:]]
            differ.append(f"its training ranges do not cover the model's: {narrow[0]}"
                          + (f" (also {', '.join(others[:2])}{', ...' if len(others) > 2 else ''})" if others else ""))
        if differ:
            more = f" (and {len(differ) - 1} more)" if len(differ) > 1 else ""
            raise SurrogateError(f"{where}: does not fit the model: {differ[0]}{more}; fit it on the model's own "
                                 "training data", param=param)

    def _range_differences(self, ranges: dict[str, tuple[float, float]]) -> list[str]:
        """Each parameter whose training range does not cover the model's, or held at another value."""
        own = self.ranges()
        out = []
        for k, (lo, hi) in ranges.items():
            if k not in own:
                continue
            a, b = own[k]
            tol = 1e-6 * max(abs(lo), abs(hi), 1e-12)
            if a > lo + tol or b < hi - tol:
                out.append(f"{k} {a:.3g}..{b:.3g} vs {lo:.3g}..{hi:.3g}")
        return out


def dataset_facts(meta: dict, split: str, stress_field: str, answers: dict[str, list[float]]) -> dict:
    """What a surrogate records of its training data (its ``dataset`` block): the frame window and interval, the
    families of the split, the stress field, the units of the design parameters and answers, and ``censored``:
    how many runs' window ended before the ball left (or before it touched), whose ``contact_end_ms`` is then the
    window's, not the ball's."""
    frames, dt = _window(meta)
    ends = np.asarray(answers.get("contact_end_ms", []), np.float64)
    censored = int(np.sum((ends >= (frames - 0.5) * dt) | (ends <= 1.5 * dt)))
    return {"frames": frames, "frame_dt_ms": dt, "split": split, "families": _families(meta, split),
            "stress_field": stress_field, "units": dict(DESIGN_UNITS), "answer_units": dict(ANSWER_UNITS),
            "censored": censored, "runs": int(len(ends))}


def _window(meta: dict | None) -> tuple[int, float]:
    """(frames, frame interval in ms) of a dataset's meta.json (0, 0.0 when it records none)."""
    settings = ((meta or {}).get("generator") or {}).get("settings") or {}
    return int(settings.get("frames") or 0), float((meta or {}).get("dt") or settings.get("frame_dt") or 0.0)


def _families(meta: dict | None, split: str = "train") -> list[str]:
    """The design families of a dataset's split (``mono`` for data made before them)."""
    listed = ((meta or {}).get("families") or {}).get(split) or ((meta or {}).get("generator") or {}).get("families")
    return sorted(set(listed or ["mono"]))


def _data_differences(facts: dict, meta: dict, stress_field: str) -> list[str]:
    """What differs between a surrogate's recorded training data (``facts``) and a model's (``meta``)."""
    frames, dt = _window(meta)
    out = []
    if facts["frames"] != frames or not math.isclose(facts["frame_dt_ms"], dt, rel_tol=1e-6):
        out.append(f"fitted on a window of {facts['frames']} frames of {facts['frame_dt_ms']:g} ms, the model's is "
                   f"{frames} frames of {dt:g} ms")
    if facts["stress_field"] != stress_field:
        out.append(f"fitted on {facts['stress_field']!r}, the model learned {stress_field!r}")
    missing = sorted(set(_families(meta)) - set(facts["families"]))
    if missing:
        out.append(f"fitted on the families {', '.join(facts['families'])}, the model trained on "
                   f"{', '.join(missing)} too")
    units = [f"{k} in {u}" for k, u in {**facts["units"], **facts["answer_units"]}.items()
             if {**DESIGN_UNITS, **ANSWER_UNITS}.get(k, u) != u]
    if units:
        out.append(f"its units differ ({', '.join(units[:3])})")
    return out


def _read_facts(facts, where: str) -> dict:
    """A version 2 file's ``dataset`` block, checked."""
    try:
        out = dict(facts)
        out.update(frames=int(out["frames"]), frame_dt_ms=float(out["frame_dt_ms"]),
                   censored=int(out["censored"]), stress_field=str(out["stress_field"]),
                   families=[str(f) for f in out["families"]],
                   units=dict(out.get("units") or {}), answer_units=dict(out.get("answer_units") or {}))
        if out["frames"] < 2 or not (math.isfinite(out["frame_dt_ms"]) and out["frame_dt_ms"] > 0) \
                or out["censored"] < 0:
            raise ValueError("frames >= 2, frame_dt_ms > 0 and censored >= 0 expected")
        return out
    except (KeyError, TypeError, ValueError) as exc:
        what = f"missing key {exc}" if isinstance(exc, KeyError) else str(exc).splitlines()[0][:120]
        raise SurrogateError(f"{where}: \"dataset\" block not usable ({what}); it is written by `hcmt surrogate "
                             "fit`") from None


def dataset_answers(data: str | Path, split: str = "train", limit: int | None = None, stress_field: str = "stress"
                    ) -> tuple[list[Design], dict[str, list[float]]]:
    """The designs of a dataset split (each trajectory's attributes) and their answers (:data:`QUANTITIES`, read
    off the solver's trajectory by :func:`hcmt.design.readout.summarize_fields`); the first ``limit`` only;
    ``stress_field``: the stress a model learned (``stress_max`` for ``generate --peak-stress`` data)."""
    data = Path(data)
    meta = read_meta(data)
    frame_dt = _window(meta)[1]
    designs, answers = [], {q: [] for q in QUANTITIES}
    with Split(data, split, meta) as s:
        count = len(s) if limit is None else min(limit, len(s))
        for i in range(count):
            attrs = s.attrs(i)
            missing = [k for k in DESIGN_KEYS[:FIRST_SCENE_KEYS] if k not in attrs]
            if missing:
                raise InputError(f"{s.path} trajectory {s.names[i]}: no design parameters {missing} in its "
                                 "attributes; a surrogate is fitted on hcmt-generated Impact Plate data")
            designs.append(design_from_attrs(attrs))
            fields = s[i]
            if stress_field not in fields:
                raise InputError(f"{s.path} trajectory {s.names[i]}: no field {stress_field!r} (a model that learned "
                                 "stress_max needs data made by `hcmt generate --peak-stress`)")
            summary = summarize_fields({**fields, "stress": fields[stress_field]}, frame_dt)
            for q in QUANTITIES:
                answers[q].append(summary[q])
    return designs, answers


def _kernel(d: int, hyper: dict | None = None):
    """c² RBF(ℓ_1..ℓ_d) + σ_n², with the stored values when ``hyper`` is given."""
    if hyper is None:
        return (ConstantKernel(1.0, (1e-3, 1e3)) * RBF(np.ones(d), (1e-2, 1e3))
                + WhiteKernel(1e-4, (1e-8, 1e-1)))
    return (ConstantKernel(float(hyper["constant"]), "fixed") * RBF(np.asarray(hyper["length_scales"], float), "fixed")
            + WhiteKernel(float(hyper["noise"]), "fixed"))


def _hyper(kernel) -> dict:
    """The fitted hyperparameters of :func:`_kernel`'s structure as plain numbers."""
    prod, white = kernel.k1, kernel.k2
    return {"constant": float(prod.k1.constant_value),
            "length_scales": [float(v) for v in np.atleast_1d(prod.k2.length_scale)],
            "noise": float(white.noise_level)}


def side_by_side(summary: dict, interval: dict[str, Interval]) -> dict:
    """The JSON block of a design's surrogate answers (``{q: {mean, lo, hi}}``) and ``disagreement``: the mesh
    model's answer (``summary``) outside the surrogate's 95 % interval, per answer and for peak plate stress."""
    block = {q: asdict(v) for q, v in interval.items()}
    outside = {q: not v.covers(summary[q]) for q, v in interval.items() if q in summary and
               isinstance(summary[q], (int, float)) and math.isfinite(summary[q])}
    return {"surrogate": block, "disagreement": bool(outside.get("peak_plate_stress_mpa", False)),
            "disagreement_by_answer": outside}


def run_surrogate_path(run) -> Path | None:
    """Where a run's own surrogate lives: ``hcmt/pretrained/NAME.surrogate.json`` beside a shipped model,
    ``RUN/surrogate.json`` in a run folder (``hcmt surrogate fit DATA --out RUN/surrogate.json``)."""
    if str(run.source).startswith("pretrained:"):
        return PRETRAINED_DIR / f"{run.source.split(':', 1)[1]}.surrogate.json"
    folder = getattr(run, "folder", None)
    return folder.path / "surrogate.json" if folder is not None else None


def run_name(run) -> str:
    """A model's name without a machine's path: ``pretrained:NAME``, or its run folder's name."""
    source = str(run.source)
    return source if source.startswith("pretrained:") else Path(source).name


def for_run(run, choice: "Surrogate | str | Path | bool | None" = True
            ) -> tuple["Surrogate | None", str | None, bool]:
    """(surrogate, note, ends_window) for a run: ``True``, the run's own (:func:`run_surrogate_path`; note when it
    has none); a path, that file; a :class:`Surrogate`, itself; ``False`` / ``None``, none. A surrogate that does
    not fit the model is refused (:meth:`Surrogate.check_model`; ``param`` surrogate when it was given).
    ``ends_window``: whether its bound of when the ball leaves may end the model's read-out window: only when its
    training window is known to be the model's (recorded, or the run's own file) and the ball left within it in
    some training run (in none: its bound is the window's end, not the ball's); otherwise the model's answer is its
    own and the note says why."""
    if choice is None or choice is False:
        return None, None, False
    own = choice is True
    if isinstance(choice, Surrogate):
        s, where = choice, "surrogate"
    elif own:
        path = run_surrogate_path(run)
        if path is None or not path.is_file():
            return None, (f"{run.source} has no response surface ({path or 'no run folder'}); fit one with "
                          "`hcmt surrogate fit DATA --out FILE` and pass --surrogate FILE"), False
        s, where = Surrogate.load(path), str(path)
        s.name = f"{run_name(run)}'s own"
    else:
        s, where = Surrogate.load(choice), str(choice)
        s.name = Path(choice).name
    stress_field = getattr(getattr(run, "adapter", None), "stress_field", "stress")
    if getattr(run, "ranges", None):
        s.check_model(run.ranges, getattr(run, "meta", None), stress_field, where, None if own else "surrogate")
    if s.censored >= len(s):
        return s, (f"{where}: in none of its {len(s)} training runs did the ball leave the plate within the window; "
                   "its bound of when the ball leaves is not used (the model's window stands)"), False
    if s.dataset is None and not own:
        return s, (f"{where}: records no training window (written before format 2, or fitted without a dataset); "
                   "its bound of when the ball leaves is not used (the model's window stands)"), False
    return s, None, True
