"""Design check, the verification: the built-in solver on the same designs (:func:`solve`) and the model against
it, per design (:func:`verify_row`, a :class:`VerifyRow`) and summarized over designs (:func:`verify_designs`, a
:class:`VerifySummary` of :class:`Stats`, with how its speedup was measured: :class:`SpeedupMeasured`)."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields, replace

import numpy as np
from tqdm import tqdm

from hcmt.config import plural
from hcmt.design.prediction import Prediction, summarize
from hcmt.design.readout import history_correlation
from hcmt.design.summary import VerifyRow
from hcmt.inference.metrics import rollout_rmse
from hcmt.inference.physics import ImpactMetrics, ImpactSummary, impact_metrics, summarize_impact
from hcmt.inference.quantities import plate_mask
from hcmt.sim.cost import validated_warnings
from hcmt.sim.driver import simulate
from hcmt.sim.params import Design, Settings


def solve(
    designs: list[tuple[str, Design]],
    settings: Settings,
    stress_field: str = "stress",
    progress: bool = False,
    bar: tqdm | None = None,
) -> list[Prediction]:
    """The built-in FEM solver on the same designs (the reference for :func:`verify`); ``stress_field``: the field
    the model learned (``stress_max``: the largest stress between frames). Each summary carries the solver's own
    warnings (``solver_warnings``: a design outside its validated ranges). ``bar``: a "solver" progress bar the
    caller keeps open over several calls (:func:`hcmt.design.check.check_designs`); else one of its own."""
    own = bar is None
    if own:
        bar = tqdm(
            total=len(designs), desc="solver", unit="design", disable=not progress or not designs, dynamic_ncols=True
        )
    out = []
    for name, design in designs:
        r = simulate(design, settings)
        f = r.fields
        p = Prediction(
            name,
            design,
            f["world_pos"],
            f[stress_field],
            f["mesh_pos"],
            f["cells"],
            f["node_type"].reshape(-1),
            r.info.wall_time,
            modulus=f["modulus"].reshape(-1),
        )
        # the solver's own quantities: the truth
        p.summary = replace(summarize(p, settings.frame_dt), solver_warnings=validated_warnings(design))
        out.append(p)
        bar.update(1)
    if own:
        bar.close()
    return out


#: the physics block's keys a verify row holds
_PHYSICS = (
    "peak_plate_stress_error_pct",
    "max_deflection_error_pct",
    "model_rebounds",
    "solver_rebounds",
    "rebound_agrees",
    "peak_plate_frame_error",
    "peak_ball_stress_error_pct",
    "far_deflection_error_um",
)


def verify_row(p: Prediction, t: Prediction) -> tuple[VerifyRow, ImpactMetrics]:
    """(the :class:`VerifyRow`, :func:`hcmt.inference.physics.impact_metrics`) of one design, model against solver;
    the peak, deflection and rebound errors are the physics block's (one definition each,
    :mod:`hcmt.inference.quantities`), the rest read off the two summaries."""
    a, b = p.summary, t.summary
    phys = impact_metrics(p.world_pos, p.stress, t.world_pos, t.stress, plate_mask(t.cells, t.node_type), 2)
    derived = {}
    if a.derived is not None:  # a derived read-out: its own error, under its own name
        derived[f"{a.readout}_peak_plate_stress_error_pct"] = float(
            100.0 * (a.derived.peak_plate_stress_mpa - b.peak_plate_stress_mpa) / b.peak_plate_stress_mpa
        )
    row = VerifyRow(
        solver_peak_plate_stress_mpa=b.peak_plate_stress_mpa,
        solver_max_deflection_mm=b.max_deflection_mm,
        **{k: getattr(phys, k) for k in _PHYSICS},
        peak_plate_location_error_mm=float(np.linalg.norm(np.subtract(a.peak_plate_where_mm, b.peak_plate_where_mm))),
        position_rmse_mm=rollout_rmse(p.world_pos, t.world_pos, 2)["rmse_all"] / 1e3,
        solver_peak_plate_t95_ms=b.peak_plate_t95_ms,
        peak_plate_t95_frame_error=int(a.peak_plate_t95_frame - b.peak_plate_t95_frame),
        critical_node_history_correlation=history_correlation(p.stress[..., 0], t.stress[..., 0], b.peak_plate_node),
        solver_wall_s=t.wall_s,
        speedup=t.wall_s / p.wall_s,
        solver_warnings=list(b.solver_warnings or []),
        readout_errors=derived,
    )
    return row, phys


@dataclass(frozen=True)
class Stats:
    """One verify quantity over designs (:func:`verify_designs`): median, max, min and mean (an error's absolute
    value: ``_pct``, ``_mm`` and ``_error`` keys)."""

    median: float
    max: float
    min: float
    mean: float

    def to_json(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class SpeedupMeasured:
    """How :func:`hcmt.design.check.check_designs` measured the speedup (:func:`speedup_measured`): ``how`` in
    words, and its parts; ``solver``: how the solver ran, in words (as ``hcmt simulate`` runs it, or with the
    between-frame peak recording a ``stress_max`` model's comparison reads). :meth:`to_json`: the JSON's
    ``speedup_measured`` block."""

    how: str
    interleaved: bool
    batch: int
    chunks: int
    device: str
    threads: int
    solver: str

    def to_json(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class VerifySummary:
    """:func:`verify_designs`: the model against the solver over designs (``Check.verified``), a :class:`Stats`
    per quantity (errors as absolute values; ``readout_errors``: a derived read-out's peak plate stress error under
    its own name, ``<readout>_peak_plate_stress_error_pct``), the physics block, the note and how the speedup was
    measured (None: not said). :meth:`to_json` is the design check's ``verify`` block."""

    designs: int
    peak_plate_stress_error_pct: Stats
    peak_plate_location_error_mm: Stats
    max_deflection_error_pct: Stats
    position_rmse_mm: Stats
    peak_plate_t95_frame_error: Stats  # the rise time (first frame at 95 % of the plate's peak)
    critical_node_history_correlation: Stats
    speedup: Stats  # solver wall time / prediction wall time per design
    physics: ImpactSummary
    note: str
    readout_errors: dict[str, Stats] = field(default_factory=dict)
    speedup_measured: SpeedupMeasured | None = None

    def to_json(self) -> dict:
        """The ``verify`` block: ``designs``, each quantity's stats in order, a derived read-out's after them, then
        ``physics``, ``note`` and ``speedup_measured`` (left out when None)."""
        out: dict[str, object] = {}
        for f in fields(self):
            if f.name == "physics":
                out.update({k: s.to_json() for k, s in self.readout_errors.items()})
            if f.name == "readout_errors" or (f.name == "speedup_measured" and self.speedup_measured is None):
                continue
            v = getattr(self, f.name)
            out[f.name] = v.to_json() if hasattr(v, "to_json") else v
        return out


#: the quantities :func:`verify_designs` summarizes, each a :class:`Stats` of :class:`VerifySummary`
STATS = tuple(f.name for f in fields(VerifySummary) if f.type in ("Stats", Stats))


def stats(values: list[float], key: str) -> Stats:
    """:class:`Stats` of one quantity over designs: an error's absolute value (``key`` ending in ``pct``, ``mm`` or
    ``error``), the non-finite values left out unless every one is."""
    v = np.array(values, np.float64)
    v = np.abs(v) if key.endswith(("pct", "mm", "error")) else v
    v = v[np.isfinite(v)] if np.isfinite(v).any() else v
    return Stats(median=float(np.median(v)), max=float(v.max()), min=float(v.min()), mean=float(v.mean()))


def verify_designs(
    preds: list[Prediction], truth: list[Prediction], measured: SpeedupMeasured | None = None
) -> VerifySummary:
    """Per design (added to each prediction's summary under ``verify``, :func:`verify_row`) and summarized over
    designs (a :class:`VerifySummary`): the model-vs-solver error of peak plate stress (%), of its location (mm), of
    maximum deflection (%), position RMSE over the window (mm, all nodes and predicted frames), the rise time and
    the speedup (solver ÷ prediction wall time); ``physics``: :func:`hcmt.inference.physics.summarize_impact` of the
    same rows (an :class:`~hcmt.inference.physics.ImpactSummary`). ``measured``: how the wall times were measured
    (:func:`speedup_measured`), recorded as ``speedup_measured`` and said in the ``note``."""
    rows, physics = [], []
    for p, t in zip(preds, truth):
        row, phys = verify_row(p, t)
        physics.append(phys)
        p.summary = replace(p.summary, verify=row, solver_plate_stress_history_mpa=t.summary.plate_stress_history_mpa)
        rows.append(row)
    how = measured.how if measured else "on this machine"
    return VerifySummary(
        designs=len(rows),
        **{k: stats([getattr(r, k) for r in rows], k) for k in STATS},
        physics=summarize_impact(physics),
        note="errors summarized as absolute values (median, max, mean); speedup = solver wall time / "
        f"prediction wall time per design, {how}",
        readout_errors={k: stats([r.readout_errors[k] for r in rows], k) for k in rows[0].readout_errors},
        speedup_measured=measured,
    )


def verify_settings(settings: Settings, stress_field: str = "stress") -> Settings:
    """The verification solver's settings: the training data's (``settings``), each node's largest stress between
    frames recorded (``peak_stress``) only where the comparison reads it, for a model that learned ``stress_max``;
    else the solver runs as ``hcmt simulate`` runs it. The recording (about 1.6x slower, one substep at a time)
    changes no frame, so the speedup divides by the solver a user runs unless the comparison needs the recording."""
    return replace(settings, peak_stress=stress_field == "stress_max")


#: how the verification's solver ran, in words (:attr:`SpeedupMeasured.solver`): with the between-frame peak
#: recording (a ``stress_max`` model's comparison reads it; slower), or as ``hcmt simulate`` runs it by default
SOLVER_RECORDING = "the solver with between-frame peak recording, which the comparison reads"
SOLVER_AS_SIMULATE = "the solver as `hcmt simulate` runs it (no between-frame peak recording)"


def speedup_measured(
    batch: int, designs: int, verify: bool | str, device: str, threads: int, solver: Settings | None = None
) -> SpeedupMeasured:
    """How :func:`hcmt.design.check.check_designs` measured the speedup: ``how`` in words, and its parts. The model
    predicts ``batch`` designs per call and the solver then runs that chunk's designs (all, or the undecided ones
    for ``verify="auto"``) before the next chunk, in the same process: both see the same load, to within a chunk.
    With one chunk of several designs (``batch`` >= ``designs`` > 1) nothing alternates: the model's batch, then
    the solver on each design (``interleaved`` False). ``solver``: the solver's settings (:func:`verify_settings`;
    None: as ``hcmt simulate`` runs it); whether it recorded each node's largest stress between frames
    (``peak_stress``, for a model that learned ``stress_max``) is said in ``solver`` and ``how``."""
    size = min(batch, designs)
    chunks = -(-designs // size)
    interleaved = chunks > 1 or size == 1
    solved = "undecided designs" if verify == "auto" else "designs"
    order = (
        f"model and solver alternating per chunk of {plural(size, 'design')} ({plural(chunks, 'chunk')}, the "
        f"solver on the chunk's {solved} right after the model's chunk)"
        if interleaved
        else f"not alternating: the model's one batch of {designs} designs, then the solver on its {solved}"
    )
    ran = SOLVER_RECORDING if solver is not None and solver.peak_stress else SOLVER_AS_SIMULATE
    return SpeedupMeasured(
        how=f"{order}, in one process, the model on {device} with {plural(threads, 'torch thread')}, {ran}",
        interleaved=interleaved,
        batch=batch,
        chunks=chunks,
        device=device,
        threads=threads,
        solver=ran,
    )
