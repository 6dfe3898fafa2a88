"""Design check, one design's numbers as typed, frozen records: :class:`Summary` (what ``Prediction.summary``
holds), its derived read-out (:class:`PlateReadout`), the model card's region of it (:class:`Confidence`), the
response surface's answers (:class:`SurrogateAnswer`) and its comparison with the solver (:class:`VerifyRow`).

A summary is the trajectory's own quantities (:class:`hcmt.inference.quantities.ImpactQuantities`, which it
extends), the read-out used, a derived read-out's peak block (``derived``), the wall time, then what the design
check adds (the model, range warnings, confidence, the surrogate's answers, the margin, the calls, the solver's
comparison). The check builds each design's summary from its read-out and adds to it with
:func:`dataclasses.replace`; an unknown field is an error there, as in the constructor.

:meth:`Summary.to_json` is each design's block of the design check's JSON (``hcmt predict --json``, beside
``name``, ``design`` and ``notes``), its keys and their order those the check wrote as plain dicts: the declared
order, a derived read-out's fields under its own names (``contact_peak_plate_stress_mpa``, ...), and a field the
check did not set (None) absent rather than null; only the trajectory's own quantities, ``readout`` and
``wall_s`` are always written, and ``confidence`` whenever the check annotated the design (``model`` set).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields

from hcmt.design.model_interval import ModelInterval
from hcmt.inference.quantities import ImpactQuantities


@dataclass(frozen=True)
class PlateReadout:
    """The plate's peak block as a derived read-out reports it (:mod:`hcmt.design.readout`): the JSON writes each
    field under the read-out's name (``<readout>_<field>``). The ``contact`` read-out also says where its window
    ended and the bending constant it used (None for another read-out: not written)."""

    peak_plate_stress_mpa: float
    peak_plate_where_mm: list[float]
    peak_plate_when_ms: float
    peak_plate_frame: int
    peak_plate_node: int
    peak_plate_t95_frame: int
    peak_plate_t95_ms: float
    plate_stress_history_mpa: list[float]
    window_end_ms: float | None = None
    window_end_from: str | None = None
    bending_k: float | None = None

    def to_json(self, readout: str) -> dict:
        """The block under ``readout``'s names, in order (a field not set left out)."""
        return {f"{readout}_{k}": v for k, v in asdict(self).items() if v is not None}


@dataclass(frozen=True)
class Confidence:
    """The model card's measured error for a design's region (:func:`hcmt.design.inputs.confidence`): the region
    (:func:`hcmt.design.inputs.region_of`), its label and how many held-out designs the card measured there, then
    the errors it measured (percent; None for ``outside``, where the card measured none). :meth:`to_json` is the
    design's ``confidence`` block of the JSON: the card's entry, a field not set left out."""

    region: str
    label: str
    designs: int
    peak_plate_stress_error_pct_median: float | None = None
    peak_plate_stress_error_pct_worst: float | None = None
    max_deflection_error_pct_median: float | None = None
    rebound_agreement: float | None = None  # the share of those designs whose rebound the model got right

    @classmethod
    def from_card(cls, entry: dict) -> Confidence:
        """A model card's ``confidence`` entry (a JSON document's dict, as ``benchmarks/release/ship_model.py``
        writes it)."""
        measured = {
            f.name: float(entry[f.name])
            for f in fields(cls)
            if f.name not in ("region", "label", "designs") and entry.get(f.name) is not None
        }
        return cls(str(entry["region"]), str(entry["label"]), int(entry["designs"]), **measured)

    def to_json(self) -> dict:
        return {k: v for k, v in asdict(self).items() if v is not None}


@dataclass(frozen=True)
class SurrogateAnswer:
    """The response surface's answer for one quantity of a design (:meth:`hcmt.design.surrogate.Surrogate.predict`,
    in the quantity's unit): its central estimate and central 95 % interval. A design's summary holds one per
    answer (``Summary.surrogate``); :meth:`to_json` is its ``{mean, lo, hi}`` block of the JSON."""

    mean: float
    lo: float
    hi: float

    def covers(self, value: float) -> bool:
        return self.lo <= value <= self.hi

    def to_json(self) -> dict:
        return {"mean": self.mean, "lo": self.lo, "hi": self.hi}


@dataclass(frozen=True)
class VerifyRow:
    """One design, model against solver: ``Summary.verify``. Stresses MPa, lengths mm (``_um``: µm), times ms;
    errors signed (model - solver), in % of the solver's value where named ``_pct``, in frames where
    ``_frame_error``. :meth:`to_json` is the design's ``verify`` block of the design check's JSON."""

    solver_peak_plate_stress_mpa: float
    solver_max_deflection_mm: float
    # the physics block's (hcmt.inference.physics.impact_metrics)
    peak_plate_stress_error_pct: float
    max_deflection_error_pct: float
    model_rebounds: bool
    solver_rebounds: bool
    rebound_agrees: bool
    peak_plate_frame_error: int
    peak_ball_stress_error_pct: float
    far_deflection_error_um: float
    # read off the two summaries
    peak_plate_location_error_mm: float
    position_rmse_mm: float  # over the window: all nodes, the predicted frames
    solver_peak_plate_t95_ms: float
    peak_plate_t95_frame_error: int  # the rise time (first frame at 95 % of the plate's peak)
    critical_node_history_correlation: float  # the model's stress history at the solver's peak node against it
    solver_wall_s: float
    speedup: float  # solver wall time / prediction wall time
    solver_warnings: list[str] = field(default_factory=list)  # the design outside the solver's validated ranges
    readout_errors: dict[str, float] = field(default_factory=dict)  # a derived read-out's peak error, by its name

    def to_json(self) -> dict:
        """The ``verify`` block: every field in order, a derived read-out's error under its own name
        (``contact_peak_plate_stress_error_pct``) last."""
        out = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "readout_errors"}
        return {**out, **self.readout_errors}


@dataclass(frozen=True)
class CallInterval:
    """The peak plate stress interval a limit call trusted (:func:`hcmt.design.calls.add_calls`), MPa: ``lo``,
    ``hi``, where it came from (``source``: ``model interval``, ``model``, ``union`` or ``surrogate``; the JSON's
    ``from``), the read-out whose peak it holds, and for a design whose call it may not decide, ``trusted`` False
    and the ``reason``. :meth:`to_json` is the design's ``call_interval_mpa`` block of the JSON."""

    lo: float
    hi: float
    source: str
    model_readout: str
    trusted: bool = True
    reason: str | None = None

    def to_json(self) -> dict:
        return {
            "lo": self.lo,
            "hi": self.hi,
            "from": self.source,
            "model_readout": self.model_readout,
            **({"trusted": False, "reason": self.reason} if not self.trusted else {}),
        }


@dataclass(frozen=True)
class Summary(ImpactQuantities):
    """One design's numbers (module docstring): stresses MPa (von Mises), lengths mm, times ms; None: not set."""

    readout: str = "raw"  # the derived read-out reported beside the model's own answer (raw: none)
    derived: PlateReadout | None = None  # that read-out's peak block (None for raw)
    wall_s: float = 0.0
    # what the design check adds
    model: str | None = None
    warnings: list[str] | None = None  # range warnings, one line each
    confidence: Confidence | None = None  # the model card's region of the design (None: the card has none)
    model_interval: ModelInterval | None = None  # the mesh model's own calibrated interval (hcmt.design.model_interval)
    surrogate: dict[str, SurrogateAnswer] | None = None  # the response surface's answers, by answer name
    disagreement: bool | None = None  # the model's peak plate stress outside the surrogate's interval
    disagreement_by_answer: dict[str, bool] | None = None
    low_confidence: bool | None = None
    yield_margin_mpa: float | None = None  # yield - peak plate stress
    derived_yield_margin_mpa: float | None = None  # yield - the derived read-out's peak (``<readout>_yield_...``)
    call: str | None = None  # pass, fail or undecided (hcmt.design.calls)
    call_interval_mpa: CallInterval | None = None  # the interval the call trusted
    verify: VerifyRow | None = None  # model against solver (hcmt.design.verification.verify_row)
    solver_plate_stress_history_mpa: list[float] | None = None
    solver_warnings: list[str] | None = None  # a solver run's own summary: the design outside its validated ranges
    verified: bool | None = None
    solver_call: str | None = None
    final_call: str | None = None

    @property
    def chosen(self) -> ImpactQuantities | PlateReadout:
        """The plate's peak block as the chosen read-out reports it: the derived one's, else the summary itself."""
        return self.derived if self.derived is not None else self

    def to_json(self) -> dict:
        """Each design's block of the design check's JSON (module docstring): the one writer of a summary."""
        out: dict[str, object] = {}
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name == "derived":
                out.update(v.to_json(self.readout) if v is not None else {})
            elif f.name == "derived_yield_margin_mpa":
                out.update({f"{self.readout}_yield_margin_mpa": v} if v is not None else {})
            elif f.name in ("confidence", "model_interval", "call_interval_mpa", "verify") and v is not None:
                out[f.name] = v.to_json()
            elif f.name == "surrogate" and v is not None:
                out[f.name] = {q: a.to_json() for q, a in v.items()}
            elif v is not None or f.name in ALWAYS or (f.name == "confidence" and self.model is not None):
                out[f.name] = v
        return out


#: the fields a summary's JSON always holds (a None among them written as null: ``contact_frames``)
ALWAYS = frozenset(f.name for f in fields(ImpactQuantities)) | {"readout", "wall_s"}
