"""Design check, its inputs: the designs a user gives (``--design K=V``, a ``--designs`` CSV, :func:`design_for`),
their names, and where they lie against a model's training data (ranges, regions, the model card's measured
confidence, the recorded window's settings)."""

from __future__ import annotations

from dataclasses import asdict, fields
from pathlib import Path

from hcmt.design.basics import read_table
from hcmt.design.summary import Confidence
from hcmt.errors import InputError, clip
from hcmt.sim.params import (
    DESIGN_KEYS,
    DESIGN_UNITS,
    FIRST_SCENE_KEYS,
    Design,
    Settings,
    a_type,
    is_number,
    parse_design,
    parse_number,
    unit_slip,
)
from hcmt.sim.sampling import EDGES, middle_design


# -- designs -----------------------------------------------------------------------------------------------------
def read_designs_csv(
    path: str | Path, defaults: Design, first: int = 1, taken: dict[str, str] | None = None
) -> list[tuple[str, Design]]:
    """Designs from a CSV file: a header of parameter names (optionally a ``name`` column), one design per row,
    every column present and numeric in every row (blank lines are skipped; a UTF-8 BOM and CRLF line ends are
    fine). Anything else is refused naming the file, the line and the column. Unnamed rows are ``design_<first>``,
    ... ; ``taken``: names already given elsewhere (name -> where), which a row may not take again."""
    path = Path(path)
    head_line, header, body = read_table(path)
    if not body:
        raise InputError(f"{path}: a header but no designs (one row per design after the header)")
    out, seen = [], dict(taken or {})
    for n, row in body:
        if len(row) != len(header):
            raise InputError(f"{path} line {n}: {len(row)} values for {len(header)} columns ({', '.join(header)})")
        name, items = f"design_{len(out) + first}", []
        for col, (h, v) in enumerate(zip(header, row), start=1):
            if h == "name":
                name = v.strip()  # a safe name: read_table checked it
                if name in seen:
                    where = seen[name] if isinstance(seen[name], str) else f"line {seen[name]}"
                    raise InputError(
                        f"{path} line {n}, column {col} (name): {clip(name)!r} already names {where}; "
                        "every design needs its own name"
                    )
                seen[name] = n
                continue
            if not v.strip():
                raise InputError(f"{path} line {n}, column {col} ({h}): missing value")
            items.append(f"{h}={parse_number(v, f'{path} line {n}, column {col} ({h})')}")
        if name in seen and seen[name] != n:
            raise InputError(
                f"{path} line {n}: the default name {name!r} is already taken ({seen[name]}); give the "
                "CSV a name column"
            )
        out.append((name, parse_design(items, defaults, where=f"{path} line {n}:")))
    return out


def with_family_defaults(ranges: dict[str, tuple[float, float]]) -> dict[str, tuple[float, float]]:
    """Training ranges with every panel-family parameter they do not name held at its default (a model trained
    before the families existed learned the first scene only); empty ranges stay empty (nothing known)."""
    if not ranges:
        return ranges
    first = {k: (v, v) for k, v in asdict(Design()).items() if k in DESIGN_KEYS[FIRST_SCENE_KEYS:]}
    return {**first, **ranges}


def outside(design: Design, ranges: dict[str, tuple[float, float]]) -> list[str]:
    """The design parameters outside ``ranges`` (relative tolerance 1e-6). A panel-family parameter that
    ``ranges`` do not name (a model trained before the families existed) counts as held at its default, the
    first scene's: one clamped layer struck by the ball."""
    out = []
    for key, (lo, hi) in with_family_defaults(ranges).items():
        tol = 1e-6 * max(abs(lo), abs(hi), 1e-12)
        if key in DESIGN_KEYS and not lo - tol <= getattr(design, key) <= hi + tol:
            out.append(key)
    return out


def range_warnings(
    design: Design, ranges: dict[str, tuple[float, float]], what: str = "the model's training data"
) -> list[str]:
    """One line per parameter outside the training data's range (:func:`outside`), naming its unit; a value more
    than ten times beyond it says so and the unit it looks typed in (:func:`hcmt.sim.params.unit_slip`: ``drop_height
    = 0.7 ... it looks like m: 700 mm?``). Such a design gets no decided call (:func:`hcmt.design.calls.add_calls`)."""
    out = []
    ranges = with_family_defaults(ranges)
    for key in outside(design, ranges):
        lo, hi = ranges[key]
        v, unit = getattr(design, key), DESIGN_UNITS.get(key, "-")
        span = (f"{lo:.6g}" if lo == hi else f"{lo:.6g} .. {hi:.6g}") + ("" if unit == "-" else f" {unit}")
        slip = unit_slip(v, unit, lo, hi) if unit != "-" else None
        out.append(f"{key} = {v:.6g} is outside {what} ({span}){'; ' + slip if slip else ''}; expect larger errors")
    return out


def region_of(design: Design, ranges: dict[str, tuple[float, float]]) -> str:
    """Where a design lies in the training ranges, for the model card's measured error by region: ``thin``
    (thickness in the lowest fifth of its range), ``high`` (drop height in the top fifth), ``thin+high``,
    ``inside``, or ``outside`` (a parameter outside the training ranges). The fifths are those of the generator's
    ``--edge-fraction`` (:data:`hcmt.sim.sampling.EDGES`)."""
    if range_warnings(design, ranges):
        return "outside"
    parts = []
    for key, name in (("thickness", "thin"), ("drop_height", "high")):
        if key in ranges:
            lo, hi = ranges[key]
            a, b = EDGES[key]
            u = (getattr(design, key) - lo) / max(hi - lo, 1e-12)
            if a <= u <= b and (a > 0 or b < 1):
                parts.append(name)
    return "+".join(parts) or "inside"


def confidence(design: Design, run) -> Confidence | None:
    """The model card's measured error for the design's region (:func:`region_of`; the card's entries are a JSON
    document's dicts), or None when the card has none."""
    regions = {r["region"]: r for r in (run.card or {}).get("confidence", [])}
    region = region_of(design, run.ranges)
    if region == "outside":
        return Confidence(region, "outside the training ranges", 0)
    return Confidence.from_card(regions[region]) if region in regions else None


def settings_of(meta: dict | None) -> Settings:
    """The generator settings (frames, frame_dt, formulation, ...) the training data was made with."""
    saved = ((meta or {}).get("generator") or {}).get("settings")
    if not saved:
        raise InputError(
            "the model's training data is not an hcmt-generated Impact Plate dataset (no generator "
            "settings in its meta.json): predict needs the recorded window it was trained on"
        )
    return Settings(**{k: v for k, v in saved.items() if k in {f.name for f in fields(Settings)}})


def check_run(run, param: str = "run"):
    """``run`` if it is a loaded model (a :class:`hcmt.Run`: its ``meta`` and ``ranges``), else one line naming
    ``param`` and how to load one (a path or ``pretrained:NAME`` given as text is not loaded here)."""
    if isinstance(run, (str, bytes, Path)) or not (hasattr(run, "meta") and hasattr(run, "ranges")):
        raise InputError(
            f"expected a loaded model, hcmt.load_pretrained(NAME) or hcmt.Run.load(PATH_OR_"
            f"'pretrained:NAME'), got {clip(repr(run))} ({a_type(run)})",
            param=param,
        )
    return run


def design_for(run, **params) -> Design:
    """An Impact Plate :class:`~hcmt.sim.params.Design` for a model: ``params`` (``thickness=0.7, ...``: numbers,
    a numpy one too) over the middle of the model's training ranges (:func:`hcmt.sim.sampling.middle_design`),
    validated (``hcmt.design_for``)."""
    check_run(run)
    for k, v in params.items():
        if not is_number(v):
            raise InputError(f"must be a number, got {clip(repr(v))} ({a_type(v)})", param=k)
    return parse_design([f"{k}={v}" for k, v in params.items()], middle_design(run.meta, run.ranges), where="design")
