"""``hcmt generate impact-plate`` and ``hcmt simulate``: write a native Impact Plate dataset, or time one design.

:func:`generate_dataset` checks its arguments and the cost, draws each trajectory's design (:mod:`hcmt.sim.sampling`)
and simulates it (:func:`hcmt.sim.driver.simulate`); :func:`hcmt.sim.writer.write_dataset` writes the dataset,
parallel, resumable and locked (trajectory ``i`` of split ``s`` draws from ``SeedSequence([seed, code(s), i])``, so
the output is identical whatever the worker count or order).
"""

from __future__ import annotations

from dataclasses import asdict

from hcmt.data.format import make_meta
from hcmt.errors import InputError
from hcmt.sim.cost import check_cost, plan
from hcmt.sim.driver import simulate
from hcmt.sim.params import CONTACT_RADIUS, FAMILIES, UNITS, Design, Settings
from hcmt.sim.sampling import RANGES, VARIANTS, checked_ranges, preset_design, sample_design
from hcmt.sim.scene import feature_spec
from hcmt.sim.writer import checked_counts, trajectory_rng, write_dataset


def trajectory_family(meta: dict, index: int) -> str:
    """The family of trajectory ``index`` of a generated dataset: its families in turn (``i mod n``)."""
    families = (meta.get("generator") or {}).get("families") or ["mono"]
    return families[index % len(families)]


def dataset_meta(
    preset: str,
    seed: int,
    counts: dict[str, int],
    settings: Settings,
    edge_fraction: float = 0.0,
    families: tuple[str, ...] = ("mono",),
    ranges: dict[str, tuple[float, float]] | None = None,
) -> dict:
    # edge_fraction, range_overrides absent: datasets made before them (or made without)
    extra: dict[str, object] = {"edge_fraction": float(edge_fraction)} if edge_fraction else {}
    if ranges:
        extra["range_overrides"] = {k: [float(lo), float(hi)] for k, (lo, hi) in ranges.items()}
    if tuple(families) != ("mono",):  # absent: one family, the first scene (datasets made before families)
        extra.update(
            families=list(families), family_ranges={f: {k: list(v) for k, v in FAMILIES[f].items()} for f in families}
        )
    generator = dict(
        name="hcmt impact-plate",
        preset=preset,
        seed=int(seed),
        counts=dict(counts),
        **extra,
        settings=asdict(settings),
        ranges={k: list(v) for k, v in {**RANGES[preset], **(ranges or {})}.items()},
        variants={k: {p: list(r) for p, r in v.items()} for k, v in VARIANTS.items()},
        contact_radius=CONTACT_RADIUS,
    )
    return make_meta(
        feature_spec(settings),
        trajectory_length=settings.frames,
        dimension=2,
        dt=settings.frame_dt,
        units=UNITS,
        generator=generator,
        dataset="impact_plate",
    )


def impact_trajectory(meta: dict, preset: str, seed: int, split: str, index: int, settings: dict) -> tuple:
    """(fields, attrs) of Impact Plate trajectory ``index`` of ``split``."""
    variant = split if split in VARIANTS else None
    edges = float(meta["generator"].get("edge_fraction", 0.0)) if split == "train" else 0.0
    override = {k: (lo, hi) for k, (lo, hi) in (meta["generator"].get("range_overrides") or {}).items()}
    design = sample_design(
        trajectory_rng(seed, split, index),
        preset,
        variant,
        edges,
        family=trajectory_family(meta, index),
        override=override,
    )
    result = simulate(design, Settings(**settings))
    return result.fields, result.attrs


def generate_dataset(
    out,
    *,
    preset: str = "small",
    counts: dict[str, int],
    seed: int = 0,
    workers: int = 1,
    settings: Settings = Settings(),
    progress: bool = True,
    edge_fraction: float = 0.0,
    families: tuple[str, ...] = ("mono",),
    force: bool = False,
    ranges: dict[str, tuple[float, float]] | None = None,
) -> dict:
    """Generate (or finish) an Impact Plate dataset in ``out``. ``counts`` maps split names (of
    :data:`hcmt.sim.writer.SPLITS`) to trajectory counts; ``edge_fraction`` of the training designs are drawn at the
    ranges' edges (thin plates, high drops: :data:`hcmt.sim.sampling.EDGES`); ``families``
    (:data:`hcmt.sim.params.FAMILIES`) take the trajectories of every split in turn, and meta.json's ``families``
    lists each trajectory's; ``ranges`` (``{name: (lo, hi)}``, ``generate --range``) replaces sampled parameters'
    ranges in every split, a variant split keeping its own range of the parameters it sets (meta.json's
    ``range_overrides``). Returns ``{"simulated": n, "skipped": n, "splits": {split: path}}``. A trajectory
    estimated at over :data:`hcmt.sim.params.MAX_ESTIMATED_SECONDS` (:func:`generation_cost`) is refused before
    anything is written, unless ``force``."""
    families, counts = _checked_arguments(preset, counts, workers, edge_fraction, families, settings)
    ranges = checked_ranges(preset, families, ranges)
    design, cost = generation_cost(preset, families, settings)
    check_cost(cost["estimated_s"], cost["num_nodes"], design, force, what=" per trajectory")
    meta = dataset_meta(preset, seed, counts, settings, edge_fraction, families, ranges)
    meta["families"] = {split: [trajectory_family(meta, i) for i in range(n)] for split, n in counts.items()}
    return write_dataset(
        out,
        meta,
        counts,
        (preset, int(seed), asdict(settings), impact_trajectory),
        workers,
        progress,
        f"impact-plate {preset}",
    )


def _checked_arguments(
    preset: str,
    counts: dict[str, int],
    workers: int,
    edge_fraction: float,
    families: tuple[str, ...],
    settings: Settings,
) -> tuple[tuple[str, ...], dict[str, int]]:
    """:func:`generate_dataset`'s arguments checked, each refusal one line naming its parameter: (the families,
    the positive counts)."""
    families = tuple(families)
    if not families:
        raise InputError(f"family: give at least one of {', '.join(FAMILIES)}")
    for f in families:
        if f not in FAMILIES:
            raise InputError(f"family {f!r} does not exist; the families are {', '.join(FAMILIES)}")
    if len(set(families)) < len(families):
        raise InputError(f"family: {', '.join(families)} names a family twice; name each once")
    if not 0.0 <= float(edge_fraction) <= 1.0:
        raise InputError(f"must be in [0, 1], got {edge_fraction}", param="edge_fraction")
    if preset not in RANGES:
        raise InputError(f"unknown preset {preset!r}; expected one of {sorted(RANGES)}")
    counts = checked_counts(counts, workers)
    if not isinstance(settings, Settings):
        raise InputError(f"must be an hcmt.Settings(...), got a {type(settings).__name__}", param="settings")
    settings.validate()
    return families, counts


def generation_cost(preset: str, families: tuple[str, ...], settings: Settings) -> tuple[Design, dict]:
    """(design, :func:`hcmt.sim.cost.plan`) of the costliest family's nominal design
    (:func:`hcmt.sim.sampling.preset_design`): what a trajectory costs."""
    return max(
        ((d, plan(d, settings)) for d in (preset_design(preset, f) for f in families)),
        key=lambda dc: dc[1]["estimated_s"],
    )
