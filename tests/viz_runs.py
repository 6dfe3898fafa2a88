"""Datasets and run folders for the viz tests: a small Impact-Plate-like dataset with units, and "runs" whose
rollout file holds a known perturbation of the ground truth (so every error the pictures and exports show is
known exactly)."""

from __future__ import annotations

import h5py
import numpy as np
import yaml

from hcmt.data.format import Split, read_meta, write_meta
from layouts import write_impact_like

SHIFT = np.array([0.03, 0.04], np.float32)  # position error of a fake run: |SHIFT| = 0.05 at every node
STRESS_OFFSET = 2.0  # stress error of a fake run


def impact_dataset(folder, n_test=1, steps=6, units=True):
    """``write_impact_like`` plus the units and time step the Impact Plate generator records."""
    write_impact_like(folder, n_test=n_test, steps=steps)
    meta = read_meta(folder)
    if units:
        meta["units"] = {"length": "mm", "time": "ms", "stress": "MPa"}
    else:
        meta["units"] = {}
    write_meta(folder, meta)
    return folder


def fake_run(run, data, split="test", model="mgn", shift=SHIFT, stress_offset=STRESS_OFFSET, start=2, levels=1):
    """A run folder whose ``rollout_<split>.h5`` is the ground truth shifted by ``shift`` (positions) and
    ``stress_offset`` (stress) from frame ``start`` on; frames before it are the data's, as a real rollout's."""
    run.mkdir(parents=True, exist_ok=True)
    info = {"model": {"name": model, "ablation": None, "levels": levels, "L_C": 1}, "data": str(data)}
    (run / "run.yaml").write_text(yaml.safe_dump(info))
    with Split(data, split) as s, h5py.File(run / f"rollout_{split}.h5", "w") as f:
        for i, name in enumerate(s.names):
            truth = s[i]
            pos = truth["world_pos"].copy()
            pos[start:] += shift
            stress = truth["stress"].copy()
            stress[start:] += stress_offset
            g = f.create_group(name)
            g["world_pos"] = pos
            g["stress"] = stress
            g.attrs["start"] = start
            g.attrs["ms_per_step"] = 1.0
    return run
