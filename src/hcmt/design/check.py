"""Design check, the check itself: the peak stress and deflection of new Impact Plate designs from a learned model,
no solver run.

For each design (the parameters of ``hcmt simulate``, :class:`hcmt.sim.scene.Design`) the generator's scene code
builds the mesh and the first two frames (:func:`hcmt.design.start.initial_frames`: the ball in free flight just above
the plate), the model rolls out over the training data's recorded window (e.g. 52 frames of 0.002 ms), several
designs as one batched graph per step (on the CPU in blocks of at most ``CPU_BLOCK_NODES`` nodes:
:func:`hcmt.inference.rollout.rollout_batch`), and :func:`summarize` reads off

* the peak von Mises stress in the plate and in the ball (MPa), where (the node's position, mm) and when (ms);
* the maximum plate deflection ``max |u_y|`` over the plate's nodes and frames (mm);
* the margin to a yield (or design) stress, ``yield - peak plate stress`` (MPa), when one is given.

:func:`check_designs` is the whole sequence (cost check, prediction with range warnings, margin, calls,
verification) that ``hcmt predict``, ``hcmt sweep`` and ``hcmt demo`` share; its parts live by job in
:mod:`hcmt.design.prediction` (rollout and read-out), :mod:`hcmt.design.calls` (limit calls),
:mod:`hcmt.design.verification` (against the solver, statistics) and :mod:`hcmt.design.notes` (low-confidence
notes), their public names importable from here as before.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import torch
from tqdm import tqdm

from hcmt.design.basics import DESIGN_BATCH, check_yield
from hcmt.design.calls import (  # noqa: F401 (re-exported: hcmt.design.check.trusted_interval, ...)
    MODEL_BAND,
    TRUST,
    TRUSTS,
    add_calls,
    add_margin,
    call_of,
    final_calls,
    trusted_interval,
)
from hcmt.design.inputs import check_run, confidence, outside, range_warnings, settings_of
from hcmt.design.model_interval import ANSWERS, Calibration, ModelInterval, for_run as interval_for_run
from hcmt.design.notes import NOTE_DISAGREEMENT, verify_hint, weak_reasons  # noqa: F401 (re-exported)
from hcmt.design.prediction import (  # noqa: F401 (re-exported)
    Prediction,
    check_design_list,
    design_trajectory,
    predict,
    predict_bar,
    predict_chunks,
    summarize,
)
from hcmt.design.readout import CONTACT_END_BOUND, DEFAULT_READOUT, check_readout
from hcmt.design.summary import Summary, SurrogateAnswer
from hcmt.design.surrogate import Surrogate
from hcmt.design.surrogate_use import for_run, side_by_side
from hcmt.design.verification import (  # noqa: F401 (re-exported)
    VerifySummary,
    solve,
    speedup_measured,
    verify_designs,
    verify_row,
    verify_settings,
)
from hcmt.errors import InputError
from hcmt.sim.cost import check_cost, check_size
from hcmt.sim.params import Design, Settings


@dataclass
class Check:
    """The result of :func:`check_designs`: predictions, the solver's runs and their comparison (``verify``).

    ``truth[i]`` is the solver's run of design ``i`` (None where it was not run: ``verify="auto"`` runs the
    solver on the undecided designs only); ``verified`` compares the designs that were run."""

    preds: list[Prediction]
    truth: list[Prediction | None] | None
    verified: VerifySummary | None
    settings: Settings
    wall_s: float  # the model's wall time over all designs (its chunks' rollouts, the solver's runs not counted)
    surrogate: str | None = None  # where the surrogate came from (None: no surrogate)
    notes: list[str] = field(default_factory=list)  # one line each: no surrogate, ...
    readout: str = DEFAULT_READOUT  # the derived read-out reported beside the model's own answer (raw: none)

    @property
    def solver_runs(self) -> int:
        return sum(t is not None for t in self.truth or [])


#: the learned rollout's cost on one CPU thread: about 1e-4 s per node and step (HCMT width 64; docs/MODELS.md)
MODEL_SECONDS_PER_NODE_STEP = 1e-4


def cost_check(run, designs: list[tuple[str, Design]], settings: Settings, verify: bool, force: bool) -> None:
    """Refuse, before any array is built, a design whose mesh exceeds :data:`hcmt.sim.cost.MAX_NODES`
    (:func:`hcmt.sim.cost.check_size`: always), and one whose estimated time (the learned rollout's, plus the
    solver's for ``verify``, from :func:`hcmt.sim.cost.estimate`) exceeds ``MAX_ESTIMATED_SECONDS`` (600 s)
    unless ``force``; as ``hcmt simulate`` does."""
    for name, d in designs:
        cost = check_size(d, settings, where=f"{name}: ")
        seconds = MODEL_SECONDS_PER_NODE_STEP * cost["num_nodes"] * (settings.frames - 2) + (
            cost["estimated_s"] if verify else 0.0
        )
        check_cost(
            seconds, cost["num_nodes"], d, force, f"{name}: ", " (model and solver)" if verify else " (model rollout)"
        )


def summary_of(p: Prediction) -> Summary:
    """A predicted design's summary: :func:`predict_chunks` summarizes every prediction it yields."""
    assert p.summary is not None, "predict_chunks summarizes every prediction it yields"
    return p.summary


def beside_model(
    p: Prediction, run, surrogate: Surrogate | None, interval: dict[str, SurrogateAnswer] | None, cannot: list[str]
) -> None:
    """The surrogate's answer beside the model's in ``p.summary`` (and its range warnings), or the warning that it
    cannot take the design."""
    summary = summary_of(p)
    warnings = list(summary.warnings or [])
    if cannot:
        warnings.append(
            f"the response surface cannot take {', '.join(cannot)} (held fixed over its training designs: "
            "another design family); no surrogate answer for this design, the call trusts the model's band"
        )
    if interval is not None:
        assert surrogate is not None, "an interval is the surrogate's answer"
        summary = side_by_side(summary, interval)
        # a user's own surrogate has its own training ranges: warn for a parameter outside them too
        own = set(outside(p.design, run.ranges))
        warnings += range_warnings(
            p.design,
            {k: r for k, r in surrogate.ranges().items() if k not in own},
            "the response surface's training designs",
        )
    p.summary = replace(summary, warnings=warnings)


def check_options(designs, verify, yield_mpa: float | None, batch: int, readout: str) -> float | None:
    """:func:`check_designs`'s designs (:func:`check_design_list`) and options, each refused naming its
    parameter; returns the yield stress as a float (:func:`hcmt.design.basics.check_yield`: a plausible one in MPa,
    a unit slip refused)."""
    check_readout(readout)
    if not (verify is True or verify is False or (isinstance(verify, str) and verify == "auto")):
        raise InputError(f"must be True, False or 'auto', got {verify!r}", param="verify")
    yield_mpa = check_yield(yield_mpa)
    if verify == "auto" and yield_mpa is None:
        raise InputError(
            "auto runs the solver on the designs whose call is undecided: it needs a yield stress "
            "(yield_mpa; --yield-mpa Y in hcmt predict and sweep)",
            param="verify",
        )
    check_design_list(designs, batch)
    return yield_mpa


def own_interval(p: Prediction, run, calibration: Calibration | None) -> ModelInterval | None:
    """The mesh model's own interval of a prediction from the run's calibration (None: none, or the design's
    cell not calibrated): :meth:`hcmt.design.model_interval.Calibration.interval` of its own answers."""
    if calibration is None:
        return None
    s = summary_of(p)
    return calibration.interval(p.design, run.ranges, {a: getattr(s, a) for a in ANSWERS}, s.plate_stress_history_mpa)


def annotate(
    p: Prediction,
    run,
    surrogate: Surrogate | None,
    interval: dict[str, SurrogateAnswer] | None,
    cannot: list[str],
    calibration: Calibration | None = None,
) -> None:
    """A prediction's summary as the check reports it: the model's name, range warnings, confidence, its own
    calibrated interval (:func:`own_interval`), the surrogate's answer beside the model's (:func:`beside_model`)
    and whether its confidence is low."""
    p.summary = replace(
        summary_of(p),
        model=run.source,
        warnings=range_warnings(p.design, run.ranges),
        confidence=confidence(p.design, run),
        model_interval=own_interval(p, run, calibration),
    )
    beside_model(p, run, surrogate, interval, cannot)
    p.summary = replace(summary_of(p), low_confidence=bool(weak_reasons(p)))


def solve_chunk(
    chunk: list[Prediction], verify: bool | str, settings: Settings, field_: str, bar: tqdm
) -> list[Prediction | None]:
    """The solver's runs of one predicted chunk, as :attr:`Check.truth` holds them: every design
    (``verify=True``), the undecided ones (``"auto"``: their calls made) or none (None where not run)."""
    if not verify:
        return [None] * len(chunk)
    chosen = [i for i, p in enumerate(chunk) if verify is True or summary_of(p).call == "undecided"]
    if verify == "auto":  # the bar learns its total chunk by chunk, as the calls are made
        bar.total += len(chosen)
        bar.refresh()
    ran = dict(zip(chosen, solve([(chunk[i].name, chunk[i].design) for i in chosen], settings, field_, bar=bar)))
    return [ran.get(i) for i in range(len(chunk))]


def check_designs(
    run,
    designs: list[tuple[str, Design]],
    *,
    batch: int = DESIGN_BATCH,
    verify: bool | str = False,
    yield_mpa: float | None = None,
    compile: str = "auto",
    progress: bool = True,
    force: bool = False,
    surrogate: Surrogate | str | Path | bool | None = True,
    readout: str = DEFAULT_READOUT,
    trust: str = TRUST,
    interval: Calibration | str | Path | bool | None = True,
) -> Check:
    """The design check, the one sequence behind ``hcmt predict``, ``hcmt sweep``, ``hcmt demo`` and
    :func:`predict_designs`: cost check, prediction (range warnings, the model's name and the confidence recorded
    in each summary), the surrogate's answers beside the model's (``surrogate``: True, the run's own; a path or a
    :class:`~hcmt.design.surrogate.Surrogate`; False / None: none; :func:`hcmt.design.surrogate_use.for_run`), the
    yield margin and the limit calls
    (:func:`add_calls`, ``trust``: which interval they trust), and the solver: on every design with
    ``verify=True``, on the undecided ones only with ``verify="auto"`` (which needs ``yield_mpa``), each chunk of
    ``batch`` designs solved right after the model predicted it. The model's
    answer is its own outputs whatever the surrogate; ``readout`` (:data:`hcmt.design.readout.READOUTS`) adds a
    derived read-out under its own names, which the calls then use (recorded as ``readout``); only ``contact``
    reads the surrogate (its bound on when the ball leaves). ``interval``: the mesh model's own calibrated
    interval (:mod:`hcmt.design.model_interval`; True, the run's own file; a path or a
    :class:`~hcmt.design.model_interval.Calibration`; False / None: none), recorded as each summary's
    ``model_interval`` and trusted by the calls. A design outside the model's training ranges gets no decided
    call unless its cell's interval was calibrated (:func:`hcmt.design.calls.add_calls`): ``verify="auto"`` runs
    the solver on it."""
    check_run(run)
    yield_mpa, batch = check_options(designs, verify, yield_mpa, batch, readout), int(batch)
    settings = settings_of(run.meta)
    calibration, interval_note = interval_for_run(run, interval)
    surrogate, note, ends_window = for_run(run, surrogate)
    notes = [n for n in (interval_note, note) if n]
    cost_check(run, designs, settings, bool(verify), force)
    intervals: list[dict[str, SurrogateAnswer] | None] | None = (
        list(surrogate.predict([d for _, d in designs])) if surrogate is not None else None
    )
    # a design with a parameter the surrogate's training designs held fixed (another family): no surrogate answer
    cannot = [surrogate.cannot_take(d) if surrogate is not None else [] for _, d in designs]
    if intervals is not None:
        intervals = [None if c else iv for iv, c in zip(intervals, cannot)]
    ends = (
        [
            getattr(iv["contact_end_ms"], CONTACT_END_BOUND) if iv and "contact_end_ms" in iv else None
            for iv in intervals
        ]
        if intervals and ends_window and readout == "contact"
        else None
    )
    field_ = run.adapter.stress_field  # stress_max: the solver records the between-frame peaks the model learned
    solver_settings = verify_settings(settings, field_)  # else it runs as `hcmt simulate` does
    # The speedup compares the solver's wall time with the model's, so both are measured under the same load: the
    # model and the solver alternate per chunk of ``batch`` designs, so a change of load on a shared machine slows
    # both alike. Everything after the rollout is per design (warnings, the surrogate beside the model, margin,
    # call), so each chunk's calls are made as soon as it is predicted, and verify="auto" solves the chunk's
    # undecided designs right after it as verify=True solves all of them: one order for both, the model timed once.
    # Only the final calls and the comparison wait for the end.
    preds: list[Prediction] = []
    truth: list[Prediction | None] = []
    with (
        predict_bar(run, designs, progress) as bar,
        tqdm(
            total=len(designs) if verify is True else 0,
            desc="solver",
            unit="design",
            disable=not progress or not verify,
            dynamic_ncols=True,
        ) as solver_bar,
    ):
        for chunk in predict_chunks(
            run, designs, batch=batch, bar=bar, compile=compile, readout=readout, contact_end_ms=ends
        ):
            for p in chunk:
                i = len(preds)
                annotate(p, run, surrogate, intervals[i] if intervals is not None else None, cannot[i], calibration)
                preds.append(p)
            add_margin(chunk, yield_mpa)
            add_calls(chunk, yield_mpa, trust, run.ranges)
            truth += solve_chunk(chunk, verify, solver_settings, field_, solver_bar)
    solved = [(p, t) for p, t in zip(preds, truth) if t is not None]  # the designs the solver ran
    measured = speedup_measured(batch, len(designs), verify, str(run.device), torch.get_num_threads(), solver_settings)
    verified = verify_designs([p for p, _ in solved], [t for _, t in solved], measured) if solved else None
    final_calls(preds, truth if verify else None, yield_mpa)
    return Check(
        preds,
        truth if verify else None,
        verified,
        settings,
        sum(p.wall_s for p in preds),
        surrogate.label if surrogate is not None else None,
        notes,
        readout,
    )


def predict_designs(
    run, designs: list[tuple[str, Design]], *, surrogate: Surrogate | str | bool | None = True, **options
) -> list[Prediction]:
    """The design check of :func:`check_designs` for Python users (``hcmt.predict_designs``): the same cost
    check, range warnings, confidence notes and, with ``surrogate=True`` (default), the run's own response surface
    beside the model (:func:`hcmt.design.surrogate_use.for_run`; a path: that file; False or None: none)."""
    return check_designs(run, designs, surrogate=surrogate, **options).preds
