"""The response surface in use beside a mesh model: which surface a model's run uses (:func:`for_run`: its own file
beside the model, :func:`run_surrogate_path`, or one given, refused when it does not fit the model) and its answers
beside the model's in a design's summary (:func:`side_by_side`, :class:`~hcmt.design.summary.SurrogateAnswer`).

It stands apart from :mod:`hcmt.design.surrogate`, the surface itself (fit, predict, store), which knows nothing of
runs, model files or the design check's summaries: this module is where the two meet, for the design check
(:mod:`hcmt.design.check`), ``hcmt models`` and the benchmarks that judge the surface against the model.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

from hcmt.data.runs import beside_model
from hcmt.design.summary import Summary, SurrogateAnswer
from hcmt.design.surrogate import Surrogate


def side_by_side(summary: Summary, interval: dict[str, SurrogateAnswer]) -> Summary:
    """A design's summary with the surrogate's fields: its answers (``surrogate``: ``interval``, by answer name)
    and ``disagreement``: the mesh model's answer (``summary``) outside the surrogate's 95 % interval, per answer
    and for peak plate stress."""
    model = {q: getattr(summary, q, None) for q in interval}  # the model's own answers (a Summary's fields)
    outside = {
        q: not v.covers(model[q])
        for q, v in interval.items()
        if isinstance(model[q], (int, float)) and math.isfinite(model[q])
    }
    return replace(
        summary,
        surrogate=dict(interval),
        disagreement=bool(outside.get("peak_plate_stress_mpa", False)),
        disagreement_by_answer=outside,
    )


def run_surrogate_path(run) -> Path | None:
    """Where a run's own surrogate lives: ``hcmt/pretrained/NAME.surrogate.json`` beside a shipped model,
    ``RUN/surrogate.json`` in a run folder (``hcmt surrogate fit DATA --out RUN/surrogate.json``)."""
    return beside_model(run, "surrogate.json")


def run_name(run) -> str:
    """A model's name without a machine's path: ``pretrained:NAME``, or its run folder's name."""
    source = str(run.source)
    return source if source.startswith("pretrained:") else Path(source).name


def for_run(run, choice: Surrogate | str | Path | bool | None = True) -> tuple[Surrogate | None, str | None, bool]:
    """(surrogate, note, ends_window) for a run: ``True``, the run's own (:func:`run_surrogate_path`; note when it
    has none); a path, that file; a :class:`~hcmt.design.surrogate.Surrogate`, itself; ``False`` / ``None``, none.
    A surrogate that does not fit the model is refused (:meth:`~hcmt.design.surrogate.Surrogate.check_model`;
    ``param`` surrogate when it was given). ``ends_window``: whether its bound of when the ball leaves may end the
    model's read-out window: only when its training window is known to be the model's (recorded, or the run's own
    file) and the ball left within it in some training run (in none: its bound is the window's end, not the
    ball's); otherwise the model's answer is its own and the note says why."""
    if choice is None or choice is False:
        return None, None, False
    own = choice is True
    if isinstance(choice, Surrogate):
        s, where = choice, "surrogate"
    elif own:
        path = run_surrogate_path(run)
        if path is None or not path.is_file():
            return (
                None,
                (
                    f"{run.source} has no response surface ({path or 'no run folder'}); fit one with "
                    "`hcmt surrogate fit DATA --out FILE` and pass --surrogate FILE"
                ),
                False,
            )
        s, where = Surrogate.load(path), str(path)
        s.name = f"{run_name(run)}'s own"
    else:
        s, where = Surrogate.load(choice), str(choice)
        s.name = Path(choice).name
    stress_field = getattr(getattr(run, "adapter", None), "stress_field", "stress")
    if getattr(run, "ranges", None):
        s.check_model(run.ranges, getattr(run, "meta", None), stress_field, where, None if own else "surrogate")
    if s.censored >= len(s):
        return (
            s,
            (
                f"{where}: in none of its {len(s)} training runs did the ball leave the plate within the window; "
                "its bound of when the ball leaves is not used (the model's window stands)"
            ),
            False,
        )
    if s.dataset is None and not own:
        return (
            s,
            (
                f"{where}: records no training window (written before format 2, or fitted without a dataset); "
                "its bound of when the ball leaves is not used (the model's window stands)"
            ),
            False,
        )
    return s, None, True
