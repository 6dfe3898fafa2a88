"""``hcmt generate deforming-plate``: a native Deforming Plate dataset (meta.json ``dataset: deforming_plate``, the
public MeshGraphNets fields and node types), written by :func:`hcmt.sim.writer.write_dataset` (parallel,
resumable, locked: the machinery the Impact Plate generator uses too)."""

from __future__ import annotations

from dataclasses import asdict

from hcmt.data.format import make_meta
from hcmt.errors import InputError
from hcmt.sim.deforming import feature_spec, simulate_plate
from hcmt.sim.params import MAX_ESTIMATED_SECONDS
from hcmt.sim.plate_params import PATHS, RANGES, SHAPES, UNITS, PlateSettings, sample_plate_design
from hcmt.sim.quasistatic import NotConverged
from hcmt.sim.writer import checked_counts, trajectory_rng, write_dataset

#: one core, measured (docs/solver.md, "Deforming Plate: cost"): seconds per load step per plate node, with the
#: ~1-2 Newton iterations a step of a 400-frame trajectory takes; the estimate behind the cost guard
SECONDS_PER_STEP_NODE = 4e-5
SPLITS = ("train", "valid", "test")
#: designs drawn for one trajectory before it is refused (:func:`deforming_trajectory`)
MAX_DRAWS = 5


def estimate_seconds(settings: PlateSettings) -> float:
    """Estimated seconds of one trajectory on one core."""
    return (settings.frames - 1) * settings.plate_nodes * SECONDS_PER_STEP_NODE


def deforming_meta(seed: int, counts: dict[str, int], settings: PlateSettings) -> dict:
    generator = dict(
        name="hcmt deforming-plate",
        seed=int(seed),
        counts=dict(counts),
        settings=asdict(settings),
        ranges={k: [lo, hi, unit] for k, (lo, hi, unit) in RANGES.items()},
        shapes=list(SHAPES),
        paths=list(PATHS),
    )
    return make_meta(
        feature_spec(settings.frames),
        trajectory_length=settings.frames,
        dimension=3,
        dt=None,
        units=UNITS,
        generator=generator,
        dataset="deforming_plate",
    )


def deforming_trajectory(meta: dict, preset: str, seed: int, split: str, index: int, settings: dict) -> tuple:
    """(fields, attrs) of Deforming Plate trajectory ``index`` of ``split`` (a :func:`write_dataset` job). A design
    whose solve does not converge even with the step halved (a box sliding deep into a thin plate: 1 of the first 15
    training designs of seed 0) is replaced by the next draw of the same stream, so the dataset stays deterministic
    and resumable; ``redraws`` records how many were replaced (at most :data:`MAX_DRAWS` - 1)."""
    rng = trajectory_rng(seed, split, index)
    for redraws in range(MAX_DRAWS):
        design = sample_plate_design(rng)
        try:
            result = simulate_plate(design, PlateSettings(**settings))
        except NotConverged:
            continue
        return result["fields"], {**result["attrs"], "redraws": redraws}
    raise NotConverged(f"{split} trajectory {index}: none of {MAX_DRAWS} designs drawn converged")


def generate_deforming_plate(
    out,
    *,
    counts: dict[str, int],
    seed: int = 0,
    workers: int = 1,
    settings: PlateSettings = PlateSettings(),
    progress: bool = True,
    force: bool = False,
) -> dict:
    """Generate (or finish) a Deforming Plate dataset in ``out``; ``counts`` maps train/valid/test to trajectory
    counts. A trajectory estimated at over :data:`hcmt.sim.params.MAX_ESTIMATED_SECONDS` is refused before anything
    is written, unless ``force``. Returns ``{"simulated": n, "skipped": n, "splits": {split: path}}``."""
    if not isinstance(settings, PlateSettings):
        raise InputError(f"must be a PlateSettings(...), got a {type(settings).__name__}", param="settings")
    settings.validate()
    counts = checked_counts(counts, workers, SPLITS)
    seconds = estimate_seconds(settings)
    if seconds > MAX_ESTIMATED_SECONDS and not force:
        raise InputError(
            f"about {settings.plate_nodes} plate nodes and {settings.frames} frames: estimated "
            f"{seconds:.0f} s per trajectory exceeds {MAX_ESTIMATED_SECONDS:.0f} s; coarsen the mesh, "
            "record fewer frames or force it (force=True, --force)"
        )
    meta = deforming_meta(seed, counts, settings)
    return write_dataset(
        out,
        meta,
        counts,
        ("deforming", int(seed), asdict(settings), deforming_trajectory),
        workers,
        progress,
        "deforming-plate",
    )
