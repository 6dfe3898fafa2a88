"""Design check, the annotation of each prediction: the surrogate's answers for the designs
(:func:`surrogate_answers`), and a predicted design's summary as the check reports it (:func:`annotate`): the
model's name, range warnings, confidence, its own calibrated interval and the surrogate's answer beside the model's."""

from __future__ import annotations

from dataclasses import dataclass, replace

from hcmt.design.inputs import confidence, outside, range_warnings
from hcmt.design.model_interval import ANSWERS, Calibration, ModelInterval
from hcmt.design.notes import weak_reasons
from hcmt.design.prediction import Prediction
from hcmt.design.readout import CONTACT_END_BOUND
from hcmt.design.summary import Summary, SurrogateAnswer
from hcmt.design.surrogate import Surrogate
from hcmt.design.surrogate_use import side_by_side
from hcmt.sim.params import Design


@dataclass(frozen=True)
class SurrogateAnswers:
    """The surrogate's answers for the check's designs, in their order (all None or empty: no surrogate):
    ``intervals[i]`` design ``i``'s answer (None where the surrogate cannot take it), ``cannot[i]`` the parameters
    it cannot take, and ``ends`` its bounds on when the ball leaves, for the ``contact`` read-out only."""

    surrogate: Surrogate | None
    intervals: list[dict[str, SurrogateAnswer] | None] | None
    cannot: list[list[str]]
    ends: list[float | None] | None

    def interval(self, i: int) -> dict[str, SurrogateAnswer] | None:
        """Design ``i``'s answer from the surrogate (None: no surrogate, or it cannot take the design)."""
        return self.intervals[i] if self.intervals is not None else None


def surrogate_answers(
    surrogate: Surrogate | None, designs: list[tuple[str, Design]], readout: str, ends_window: bool
) -> SurrogateAnswers:
    """The surrogate's answers for the designs (:class:`SurrogateAnswers`): its bounds on when the ball leaves only
    for the ``contact`` read-out and where they may end the model's window (``ends_window``:
    :func:`hcmt.design.surrogate_use.for_run`)."""
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
    return SurrogateAnswers(surrogate, intervals, cannot, ends)


def summary_of(p: Prediction) -> Summary:
    """A predicted design's summary: :func:`hcmt.design.prediction.predict_chunks` summarizes every prediction it
    yields."""
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


def annotate_chunk(
    chunk: list[Prediction], first: int, run, answers: SurrogateAnswers, calibration: Calibration | None
) -> None:
    """Each prediction of a chunk annotated (:func:`annotate`) with its design's answers, ``first`` the index of the
    chunk's first design among the check's designs."""
    for i, p in enumerate(chunk, first):
        annotate(p, run, answers.surrogate, answers.interval(i), answers.cannot[i], calibration)
