"""Where the mesh model's stress after the ball leaves comes from: its stress head or its rollout.

    python benchmarks/ghost_diagnosis/run.py --data DATA [--run pretrained:impact_plate_small] [--split valid]
                                         [--limit N] [--threads 1] [--json benchmarks/results/ghost_diagnosis.json]

For every trajectory of the split, the plate's stress history three ways, each read with
:mod:`hcmt.inference.quantities` (plate mask, ``body_history``, ``ghost_ratio``, ``contact_end_frame``):

* **solver**: the data;
* **rollout**: the model's own autoregressive prediction (what ``hcmt predict`` reports);
* **teacher-forced**: the model's one-step stress from the solver's own state at every frame (``x^t``, ``x^{t-1}``
  of the data), so the stress head sees the right positions, contact and deflection.

* **perturbed**: the rollout again from first frames moved by ``--perturb`` mm (Gaussian, every node), a size far
  below any error the model makes; its distance from the rollout per frame says how fast the learned dynamics
  amplify a small error (``amplification``: the largest node distance at the last frame ÷ the perturbation).

If the teacher-forced ghost ratio matches the solver's while the rollout's does not, the stress head lets go and the
stress that stays comes from the rollout's state (the ball leaving late, the plate unloading late): the remedy is in
the dynamics, not in the stress head's inputs. If the perturbed rollout's ghost ratio moves by as much as the
rollout's error, that state is set by amplified error: training for stability (noise, pushforward), not the stress
head, is the remedy.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

import h5py
import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # benchmarks/: common
from common import RESULTS, write_json  # noqa: E402
from hcmt.domains.frames import input_graph  # noqa: E402
from hcmt.domains.trajectory import load_split  # noqa: E402
from hcmt.inference import quantities as q  # noqa: E402
from hcmt.inference.rollout import rollout  # noqa: E402
from hcmt.inference.run import Run  # noqa: E402


@torch.no_grad()
def teacher_forced_stress(run: Run, tr) -> np.ndarray:
    """[T, N] the model's one-step stress from the data's state at every frame (the data's first frames kept)."""
    model, w, h = run.model.eval(), tr.world_pos, run.adapter.history
    out = tr.stress[..., 0].numpy().astype(np.float64).copy()
    for t in range(h, w.shape[0] - 1):
        graph = input_graph(tr, w[t], w[t - h], w[t + 1], run.radius)
        out[t + 1] = model.denormalize(model(graph))[:, -1].double().numpy()
    return out


def summary(stress: np.ndarray, world_pos: np.ndarray, rest: np.ndarray, plate: np.ndarray) -> dict:
    history = q.body_history(stress, plate)
    peak = float(history.max())
    return {
        "peak_mpa": peak,
        "ghost_ratio": q.ghost_ratio(history, peak),
        "max_deflection_mm": q.max_deflection(world_pos, rest, plate),
        "contact_end_frame": int(q.contact_end_frame(q.contact_gap(world_pos, rest, plate))),
    }


def perturbed(tr, size: float, seed: int):
    """``tr`` with its first ``history + 1`` frames moved by Gaussian noise of ``size`` mm (later frames: as read by
    the boundary conditions, unchanged)."""
    w = tr.world_pos.clone()
    h = tr.adapter.history
    g = torch.Generator().manual_seed(seed)
    w[: h + 1] += size * torch.randn(w[: h + 1].shape, generator=g, dtype=w.dtype)
    return dataclasses.replace(tr, world_pos=w)


def diagnose(run: Run, data: Path, split: str, limit: int | None, perturb: float = 1e-6) -> list[dict]:
    levels, remesh = run.hierarchy_spec
    rows = []
    with h5py.File(data / f"{split}.h5", "r") as f:
        for tr in load_split(data, split, run.adapter, levels, remesh, limit=limit):
            plate = q.plate_mask(f[tr.name]["cells"][()], tr.static["node_type"].numpy().ravel())
            true_pos, rest = tr.world_pos.numpy(), tr.world_pos[0].numpy()
            pred = rollout(run.model, run.adapter, tr, run.radius)
            moved = rollout(run.model, run.adapter, perturbed(tr, perturb, len(rows)), run.radius)
            gap = (moved["world_pos"] - pred["world_pos"]).abs().amax(dim=(1, 2)).numpy()
            row = {
                "trajectory": tr.name,
                "solver": summary(tr.stress.numpy(), true_pos, rest, plate),
                "rollout": summary(pred["stress"].numpy(), pred["world_pos"].numpy(), rest, plate),
                "teacher_forced": summary(teacher_forced_stress(run, tr), true_pos, rest, plate),
                "perturbed": summary(moved["stress"].numpy(), moved["world_pos"].numpy(), rest, plate),
                "perturbed_distance_mm": [float(x) for x in gap],
                "amplification": float(gap[-1] / perturb),
            }
            rows.append(row)
            print(
                f"{tr.name}: ghost ratio solver {row['solver']['ghost_ratio']:.2f}, rollout "
                f"{row['rollout']['ghost_ratio']:.2f}, teacher-forced {row['teacher_forced']['ghost_ratio']:.2f}; "
                f"ball leaves at frame {row['solver']['contact_end_frame']} (solver), "
                f"{row['rollout']['contact_end_frame']} (rollout); a {perturb:g} mm perturbation grows "
                f"{row['amplification']:.1e}x, perturbed ghost ratio {row['perturbed']['ghost_ratio']:.2f}",
                flush=True,
            )
    return rows


def medians(rows: list[dict]) -> dict:
    def med(values):
        return float(np.median(values))

    ghost = {
        k: [abs(r[k]["ghost_ratio"] - r["solver"]["ghost_ratio"]) for r in rows]
        for k in ("rollout", "teacher_forced", "perturbed")
    }

    def error(key):  # |rollout / solver - 1| of a summary's value
        return med([abs(r["rollout"][key] / r["solver"][key] - 1) for r in rows])

    return {
        "ghost_difference_median": {k: med(v) for k, v in ghost.items()},
        "solver_ghost_ratio_median": med([r["solver"]["ghost_ratio"] for r in rows]),
        "rollout_ghost_ratio_median": med([r["rollout"]["ghost_ratio"] for r in rows]),
        "teacher_forced_ghost_ratio_median": med([r["teacher_forced"]["ghost_ratio"] for r in rows]),
        "perturbed_ghost_shift_median": med(
            [abs(r["perturbed"]["ghost_ratio"] - r["rollout"]["ghost_ratio"]) for r in rows]
        ),
        "amplification_median": med([r["amplification"] for r in rows]),
        "peak_error_median": error("peak_mpa"),
        "deflection_error_median": error("max_deflection_mm"),
        "contact_end_frames_late_median": med(
            [r["rollout"]["contact_end_frame"] - r["solver"]["contact_end_frame"] for r in rows]
        ),
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", type=Path, required=True)
    p.add_argument("--run", default="pretrained:impact_plate_small")
    p.add_argument("--split", default="valid")
    p.add_argument("--limit", type=int)
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--perturb", type=float, default=1e-6, help="mm moved at the first frames (default 1e-6)")
    p.add_argument("--json", type=Path, default=RESULTS / "ghost_diagnosis.json")
    a = p.parse_args()
    torch.set_num_threads(a.threads)
    run = Run.load(a.run, "cpu")
    rows = diagnose(run, a.data, a.split, a.limit, a.perturb)
    out = {
        "command": "python benchmarks/ghost_diagnosis/run.py " + " ".join(sys.argv[1:]),
        "run": a.run,
        "split": a.split,
        "perturb_mm": a.perturb,
        "trajectories": len(rows),
        **medians(rows),
        "rows": rows,
    }
    print(json.dumps({k: v for k, v in out.items() if k != "rows"}, indent=1))
    write_json(a.json, out)


if __name__ == "__main__":
    main()
