"""Design check, one design's numbers as typed fields: :class:`Summary`, what ``Prediction.summary`` holds.

Its fields are the keys of the design check's JSON (``hcmt predict --json``: each design's block, beside ``name``,
``design`` and ``notes``), unchanged: the trajectory's own quantities (:func:`hcmt.inference.quantities.
impact_summary`), the read-out used and the wall time, then what the check adds (the model, range warnings,
confidence, the surrogate's answers, the margin, the calls, the solver's comparison). A derived read-out's fields
(``contact_*``, ``element_*``: :mod:`hcmt.design.readout`) and any other key go to ``extra``. A field not set is
absent from the JSON (not null), and the keys keep the order they were set in, as the dicts did before:
:meth:`Summary.to_json` writes the same keys in the same order. It reads and writes as a mapping too
(``summary["call"]``, ``summary.get("verify")``, ``"verify" in summary``, ``{**summary}``)."""
from __future__ import annotations

from collections.abc import Iterator, Mapping, MutableMapping
from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from hcmt.design.verification import VerifyRow


@dataclass(eq=False)
class Summary(MutableMapping):
    """One design's numbers (module docstring): stresses MPa (von Mises), lengths mm, times ms; None: not set."""

    # the trajectory's own quantities
    peak_plate_stress_mpa: float | None = None
    peak_plate_where_mm: list[float] | None = None  # (r, y) of the peak's node at its frame
    peak_plate_when_ms: float | None = None
    peak_plate_frame: int | None = None
    peak_plate_node: int | None = None
    peak_ball_stress_mpa: float | None = None
    peak_ball_where_mm: list[float] | None = None
    peak_ball_when_ms: float | None = None
    peak_ball_frame: int | None = None
    peak_ball_node: int | None = None
    peak_plate_t95_frame: int | None = None  # first frame at 95 % of the peak (the rise time)
    peak_plate_t95_ms: float | None = None
    max_deflection_mm: float | None = None  # max |u_y| over the plate's nodes and frames
    far_deflection_mm: float | None = None
    contact_frames: int | None = None
    contact_end_ms: float | None = None
    ghost_ratio: float | None = None
    rebounds: bool | None = None
    plate_stress_history_mpa: list[float] | None = None  # the plate's peak stress per frame
    readout: str | None = None  # the derived read-out reported beside the model's own answer (raw: none)
    wall_s: float | None = None
    # what the design check adds
    model: str | None = None
    warnings: list[str] | None = None  # range warnings, one line each
    confidence: dict | None = None  # the model card's region of the design
    surrogate: dict | None = None  # the response surface's answers {key: {mean, lo, hi}}
    disagreement: float | None = None
    disagreement_by_answer: dict | None = None
    low_confidence: bool | None = None
    yield_margin_mpa: float | None = None  # yield - peak plate stress
    call: str | None = None  # pass, fail or undecided (hcmt.design.calls)
    call_interval_mpa: dict | None = None  # {lo, hi, from, model_readout}
    verify: VerifyRow | None = None  # model against solver (hcmt.design.verification.verify_row)
    solver_plate_stress_history_mpa: list[float] | None = None
    solver_warnings: list[str] | None = None
    verified: bool | None = None
    solver_call: str | None = None
    final_call: str | None = None
    extra: dict = field(default_factory=dict)  # contact_* / element_* read-out fields and any other key

    def __post_init__(self) -> None:
        object.__setattr__(self, "_keys", [k for k in KEYS if getattr(self, k) is not None])

    @classmethod
    def of(cls, values: Mapping) -> "Summary":
        """A summary holding ``values`` (e.g. :func:`hcmt.design.readout.summarize_fields`'s dict), in order."""
        out = cls()
        out.update(values)
        return out

    def __setattr__(self, name: str, value) -> None:
        object.__setattr__(self, name, value)
        keys = self.__dict__.get("_keys")
        if keys is not None and name in KEYS and name not in keys:
            keys.append(name)

    def __getitem__(self, key: str):
        if key not in self._keys:
            raise KeyError(key)
        return getattr(self, key) if key in KEYS else self.extra[key]

    def __setitem__(self, key: str, value) -> None:
        if key in KEYS:
            setattr(self, key, value)
            return
        self.extra[key] = value
        if key not in self._keys:
            self._keys.append(key)

    def __delitem__(self, key: str) -> None:
        if key not in self._keys:
            raise KeyError(key)
        self._keys.remove(key)
        if key in KEYS:
            object.__setattr__(self, key, None)
        else:
            del self.extra[key]

    def __iter__(self) -> Iterator[str]:
        return iter(list(self._keys))

    def __len__(self) -> int:
        return len(self._keys)

    def __repr__(self) -> str:
        return f"Summary({', '.join(f'{k}={self[k]!r}' for k in self)})"

    def to_json(self) -> dict:
        """The keys set, in the order they were set: each design's block of the design check's JSON (``verify``:
        :meth:`hcmt.design.verification.VerifyRow.to_json`)."""
        return {k: self[k].to_json() if k == "verify" and hasattr(self[k], "to_json") else self[k] for k in self}


#: the typed keys of a summary (every field but ``extra``)
KEYS = frozenset(f.name for f in fields(Summary) if f.name != "extra")
