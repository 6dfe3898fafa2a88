"""Design check, the prediction: each design's rollout input from the generator's scene code
(:func:`design_trajectory`: the ball in free flight just above the plate), the model rolled out over the training
data's recorded window, ``batch`` designs as one batched graph per step
(on the CPU in blocks of at most ``CPU_BLOCK_NODES`` nodes: :func:`hcmt.inference.rollout.rollout_batch`), and the
numbers read off (:func:`summarize`, :func:`hcmt.design.readout.summarize_fields`) into :class:`Prediction`."""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from tqdm import tqdm

from hcmt.config import MAX_BATCH, MAX_DESIGNS
from hcmt.design.basics import DESIGN_BATCH, check_name
from hcmt.design.inputs import settings_of
from hcmt.design.readout import DEFAULT_READOUT, check_readout, summarize_fields
from hcmt.design.start import start_frames
from hcmt.design.summary import Summary
from hcmt.domains.trajectory import prepare_trajectory
from hcmt.errors import InputError, clip
from hcmt.inference.rollout import rollout_batch, rollout_compile
from hcmt.sim.params import Design, Settings, is_number


@dataclass
class Prediction:
    """One design's predicted (or simulated) trajectory and what it was made from."""

    name: str
    design: Design
    world_pos: np.ndarray  # [T, N, 2] mm
    stress: np.ndarray  # [T, N, 1] MPa (von Mises)
    mesh_pos: np.ndarray  # [N, 2]
    cells: np.ndarray  # [C, 3]
    node_type: np.ndarray  # [N]
    wall_s: float  # seconds spent on this design (a batch's wall time split evenly over its designs)
    summary: Summary | None = None  # the numbers read off (:func:`summarize`; the check adds to them)
    modulus: np.ndarray | None = None  # [N] MPa (the bending read-out after the ball has left)

    def fields(self) -> dict:
        """The trajectory as :func:`hcmt.design.readout.summarize_fields` reads it."""
        return {
            "world_pos": self.world_pos,
            "stress": self.stress,
            "mesh_pos": self.mesh_pos,
            "cells": self.cells,
            "node_type": self.node_type,
            "modulus": self.modulus,
        }


def design_trajectory(run, name: str, design: Design, settings: Settings):
    """The rollout input of a design: frames 0 and 1 from :func:`hcmt.design.start.start_frames` (the solver's first
    frame only when the ball reaches the plate within it), later frames holding only what the boundary conditions
    read (the clamped rim and the symmetry line do not move: frame 0's positions)."""
    start = start_frames(design, settings)
    f = dict(start["fields"])
    x = f["world_pos"]
    f["world_pos"] = np.concatenate([x, np.repeat(x[:1], settings.frames - 2, axis=0)])
    f["stress"] = f[run.adapter.stress_field] = np.zeros((settings.frames, x.shape[1], 1), np.float32)
    levels, remesh = run.hierarchy_spec
    return prepare_trajectory(f, name, run.adapter, levels, remesh, attrs=start["attrs"]), f


def check_design_list(designs, batch: int = 1) -> None:
    """Refuse (``param="designs"``) what is not 1 to :data:`hcmt.config.MAX_DESIGNS` pairs (name, valid
    :class:`~hcmt.sim.scene.Design`) with safe, distinct names (:func:`hcmt.design.basics.check_name`): the checks
    a ``--designs`` CSV gets, for the Python API; and a ``batch`` that is no whole number from 1 to
    :data:`hcmt.config.MAX_BATCH`."""
    if not is_number(batch, whole=True) or not 1 <= batch <= MAX_BATCH:  # a numpy integer is one; a bool is not
        raise InputError(f"must be a whole number from 1 to {MAX_BATCH:,}, got {clip(repr(batch))}", param="batch")
    if not isinstance(designs, (list, tuple)) or not 1 <= len(designs) <= MAX_DESIGNS:
        got = f"{len(designs):,} items" if isinstance(designs, (list, tuple)) else type(designs).__name__
        raise InputError(f"expected a list of 1 to {MAX_DESIGNS:,} (name, Design) pairs, got {got}", param="designs")
    seen: dict[str, int] = {}
    for i, item in enumerate(designs):
        if not (isinstance(item, (list, tuple)) and len(item) == 2 and isinstance(item[1], Design)):
            raise InputError(
                f"item {i}: expected a (name, Design) pair, e.g. ('a', hcmt.design_for(run, "
                f"thickness=0.7)), got {clip(repr(item))}",
                param="designs",
            )
        try:
            check_name(item[0], f"item {i}")
        except InputError as exc:
            raise InputError(str(exc), param="designs") from None
        try:
            item[1].validate()
        except InputError as exc:
            raise InputError(f"item {i} ({clip(item[0])!r}): {exc}", param="designs") from None
        if item[0] in seen:
            raise InputError(
                f"item {i}: the name {clip(item[0])!r} already names item {seen[item[0]]}; every design "
                "needs its own name",
                param="designs",
            )
        seen[item[0]] = i


def predict_bar(run, designs: list, progress: bool) -> tqdm:
    """The "predict" progress bar over the designs' rollout steps (silent unless ``progress``)."""
    h = run.adapter.history
    return tqdm(
        total=len(designs) * (settings_of(run.meta).frames - 1 - h),
        desc="predict",
        unit="step",
        disable=not progress,
        dynamic_ncols=True,
    )


def predict_chunks(
    run,
    designs: list[tuple[str, Design]],
    batch: int,
    bar: tqdm,
    compile: str = "auto",
    readout: str = DEFAULT_READOUT,
    contact_end_ms: list[float | None] | None = None,
) -> Iterator[list[Prediction]]:
    """:func:`predict` one chunk of ``batch`` designs at a time (its options unchecked: the caller checked them),
    each chunk's predictions yielded as soon as they are made: each ``wall_s`` is its own chunk's wall time split
    over its designs, whatever the caller does between chunks (:func:`hcmt.design.check.check_designs` runs the
    solver there)."""
    settings = settings_of(run.meta)
    compile = rollout_compile(compile, run.model, len(designs) * (settings.frames - 1 - run.adapter.history))
    for first in range(0, len(designs), batch):
        chunk = designs[first : first + batch]
        t0 = time.perf_counter()
        built = [design_trajectory(run, name, d, settings) for name, d in chunk]
        results = rollout_batch(
            run.model,
            run.adapter,
            [tr for tr, _ in built],
            run.radius,
            compile=compile,
            progress=lambda n, k=len(chunk): bar.update(n * k),
        )
        wall = (time.perf_counter() - t0) / len(chunk)
        out = []
        for k, ((name, design), (_, f), r) in enumerate(zip(chunk, built, results)):
            p = Prediction(
                name,
                design,
                r["world_pos"].numpy(),
                r["stress"].numpy(),
                f["mesh_pos"],
                f["cells"],
                f["node_type"].reshape(-1),
                wall,
                modulus=f["modulus"].reshape(-1),
            )
            end = contact_end_ms[first + k] if contact_end_ms is not None else None
            p.summary = summarize(p, settings.frame_dt, readout, end)
            out.append(p)
        yield out


def predict(
    run,
    designs: list[tuple[str, Design]],
    batch: int = DESIGN_BATCH,
    progress: bool = True,
    compile: str = "auto",
    readout: str = DEFAULT_READOUT,
    contact_end_ms: list[float | None] | None = None,
) -> list[Prediction]:
    """Roll the run's model out over each design's recorded window, ``batch`` designs per model call
    (``compile``: as :func:`hcmt.inference.rollout.rollout_batch`, ``auto`` for all the designs' steps together:
    :func:`hcmt.inference.rollout.rollout_compile`); ``readout``: a derived read-out reported
    beside the model's own answer under its own names (:data:`hcmt.design.readout.READOUTS`; default none);
    ``contact_end_ms``: per design, the ``contact`` read-out's bound on when the ball leaves, or None."""
    check_readout(readout)
    check_design_list(designs, batch)
    with predict_bar(run, designs, progress) as bar:
        return [
            p for chunk in predict_chunks(run, designs, batch, bar, compile, readout, contact_end_ms) for p in chunk
        ]


def summarize(
    p: Prediction, frame_dt: float, readout: str = DEFAULT_READOUT, contact_end_ms: float | None = None
) -> Summary:
    """The trajectory's own quantities (peak plate and ball stress, where, when, rise time, deflection, the plate's
    stress history, ...) and a derived ``readout``'s under its own names
    (:func:`hcmt.design.readout.summarize_fields`), as a :class:`~hcmt.design.summary.Summary`."""
    return summarize_fields(p.fields(), frame_dt, readout, p.wall_s, contact_end_ms)
