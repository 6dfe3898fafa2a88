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
:mod:`hcmt.design.prediction` (rollout and read-out), :mod:`hcmt.design.annotation` (each prediction's summary as
the check reports it, the surrogate's answers), :mod:`hcmt.design.calls` (limit calls),
:mod:`hcmt.design.verification` (against the solver, statistics) and :mod:`hcmt.design.notes` (low-confidence
notes), their public names importable from here as before.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import torch
from tqdm import tqdm

from hcmt.design.annotation import (  # noqa: F401 (re-exported: hcmt.design.check.own_interval, ...)
    SurrogateAnswers,
    annotate,
    annotate_chunk,
    beside_model,
    own_interval,
    summary_of,
    surrogate_answers,
)
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
from hcmt.design.inputs import check_run, settings_of
from hcmt.design.model_interval import Calibration, for_run as interval_for_run
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
from hcmt.design.readout import DEFAULT_READOUT, check_readout
from hcmt.design.surrogate import Surrogate
from hcmt.design.surrogate_use import for_run
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


@dataclass(frozen=True)
class Plan:
    """What :func:`check_designs` resolved before its first chunk, its options checked: what each chunk's steps
    (:func:`check_chunk`) and the check's end (:func:`verify_and_call`) take."""

    run: Any
    designs: list[tuple[str, Design]]
    batch: int
    verify: bool | str
    yield_mpa: float | None
    trust: str
    readout: str
    calibration: Calibration | None
    answers: SurrogateAnswers
    solver_settings: Settings  # the solver's settings for the verification (:func:`verify_settings`)
    field_: str  # the stress field the solver records (the run's adapter's)


def solver_bar(designs: list, verify: bool | str, progress: bool) -> tqdm:
    """The "solver" progress bar over the designs the solver runs: all of them (``verify=True``), or a total that
    :func:`solve_chunk` grows chunk by chunk (``"auto"``); silent unless ``progress`` and ``verify``."""
    return tqdm(
        total=len(designs) if verify is True else 0,
        desc="solver",
        unit="design",
        disable=not progress or not verify,
        dynamic_ncols=True,
    )


def check_chunk(chunk: list[Prediction], first: int, plan: Plan, bar: tqdm) -> list[Prediction | None]:
    """One predicted chunk's steps, in order: its designs annotated (``first``: the index of its first design),
    their margins and calls, then the solver's runs of it (:func:`solve_chunk`), which it returns."""
    annotate_chunk(chunk, first, plan.run, plan.answers, plan.calibration)
    add_margin(chunk, plan.yield_mpa)
    add_calls(chunk, plan.yield_mpa, plan.trust, plan.run.ranges)
    return solve_chunk(chunk, plan.verify, plan.solver_settings, plan.field_, bar)


def predict_and_solve(plan: Plan, compile: str, progress: bool) -> tuple[list[Prediction], list[Prediction | None]]:
    """The model's predictions of the designs, a chunk of ``batch`` designs at a time, each chunk's steps
    (:func:`check_chunk`) right after it: (predictions, the solver's runs as :attr:`Check.truth` holds them)."""
    # The speedup compares the solver's wall time with the model's, so both are measured under the same load: the
    # model and the solver alternate per chunk of ``batch`` designs, so a change of load on a shared machine slows
    # both alike. Everything after the rollout is per design (warnings, the surrogate beside the model, margin,
    # call), so each chunk's calls are made as soon as it is predicted, and verify="auto" solves the chunk's
    # undecided designs right after it as verify=True solves all of them: one order for both, the model timed once.
    # Only the final calls and the comparison wait for the end.
    run, designs = plan.run, plan.designs
    preds: list[Prediction] = []
    truth: list[Prediction | None] = []
    with predict_bar(run, designs, progress) as bar, solver_bar(designs, plan.verify, progress) as solver:
        for chunk in predict_chunks(
            run,
            designs,
            batch=plan.batch,
            bar=bar,
            compile=compile,
            readout=plan.readout,
            contact_end_ms=plan.answers.ends,
        ):
            truth += check_chunk(chunk, len(preds), plan, solver)
            preds += chunk
    return preds, truth


def verify_and_call(plan: Plan, preds: list[Prediction], truth: list[Prediction | None]) -> VerifySummary | None:
    """The check's end, once every chunk is done: the model against the solver on the designs the solver ran
    (None: none ran), then the final calls (:func:`final_calls`: the solver's answers where it ran)."""
    solved = [(p, t) for p, t in zip(preds, truth) if t is not None]  # the designs the solver ran
    measured = speedup_measured(
        plan.batch, len(plan.designs), plan.verify, str(plan.run.device), torch.get_num_threads(), plan.solver_settings
    )
    verified = verify_designs([p for p, _ in solved], [t for _, t in solved], measured) if solved else None
    final_calls(preds, truth if plan.verify else None, plan.yield_mpa)
    return verified


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
    answers = surrogate_answers(surrogate, designs, readout, ends_window)
    field_ = run.adapter.stress_field  # stress_max: the solver records the between-frame peaks the model learned
    solver_settings = verify_settings(settings, field_)  # else it runs as `hcmt simulate` does
    plan = Plan(run, designs, batch, verify, yield_mpa, trust, readout, calibration, answers, solver_settings, field_)
    preds, truth = predict_and_solve(plan, compile, progress)
    verified = verify_and_call(plan, preds, truth)
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
