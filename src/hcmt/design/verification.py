"""Design check, the verification: the built-in solver on the same designs (:func:`solve`) and the model against
it, per design (:func:`verify_row`) and summarized over designs (:func:`verify_designs`, :func:`stats`)."""
from __future__ import annotations

import numpy as np
from tqdm import tqdm

from hcmt.design.prediction import Prediction, summarize
from hcmt.design.readout import DEFAULT_READOUT, history_correlation, readout_key
from hcmt.inference.metrics import impact_metrics, rollout_rmse, summarize_impact
from hcmt.inference.quantities import plate_mask
from hcmt.sim.cost import validated_warnings
from hcmt.sim.driver import simulate
from hcmt.sim.params import Design, Settings


def solve(designs: list[tuple[str, Design]], settings: Settings, stress_field: str = "stress",
          progress: bool = False) -> list[Prediction]:
    """The built-in FEM solver on the same designs (the reference for :func:`verify`); ``stress_field``: the field
    the model learned (``stress_max``: the largest stress between frames). Each summary carries the solver's own
    warnings (``solver_warnings``: a design outside its validated ranges)."""
    out = []
    for name, design in tqdm(designs, desc="solver", unit="design", disable=not progress or not designs,
                             dynamic_ncols=True):
        r = simulate(design, settings)
        f = r["fields"]
        p = Prediction(name, design, f["world_pos"], f[stress_field], f["mesh_pos"], f["cells"],
                       f["node_type"].reshape(-1), r["info"]["wall_time"], modulus=f["modulus"].reshape(-1))
        p.summary = summarize(p, settings.frame_dt)  # the solver's own quantities: the truth
        p.summary["solver_warnings"] = validated_warnings(design)
        out.append(p)
    return out


def verify_row(p: Prediction, t: Prediction) -> tuple[dict, dict]:
    """(the verify row, :func:`hcmt.inference.metrics.impact_metrics`) of one design, model against solver; the
    peak, deflection and rebound errors are the physics block's (one definition each,
    :mod:`hcmt.inference.quantities`), the rest read off the two summaries."""
    a, b = p.summary, t.summary
    phys = impact_metrics(p.world_pos, p.stress, t.world_pos, t.stress, plate_mask(t.cells, t.node_type), 2)
    row = {
        "solver_peak_plate_stress_mpa": b["peak_plate_stress_mpa"],
        "solver_max_deflection_mm": b["max_deflection_mm"],
        **{k: phys[k] for k in ("peak_plate_stress_error_pct", "max_deflection_error_pct", "model_rebounds",
                                "solver_rebounds", "rebound_agrees", "peak_plate_frame_error",
                                "peak_ball_stress_error_pct", "far_deflection_error_um")},
        "peak_plate_location_error_mm": float(np.linalg.norm(np.subtract(a["peak_plate_where_mm"],
                                                                         b["peak_plate_where_mm"]))),
        "position_rmse_mm": rollout_rmse(p.world_pos, t.world_pos, 2)["rmse_all"] / 1e3,
        "solver_peak_plate_t95_ms": b["peak_plate_t95_ms"],
        "peak_plate_t95_frame_error": int(a["peak_plate_t95_frame"] - b["peak_plate_t95_frame"]),
        # the solver's critical node (its peak's node): does the model's stress there rise and fall with it?
        "critical_node_history_correlation": history_correlation(p.stress[..., 0], t.stress[..., 0],
                                                                 b["peak_plate_node"]),
        "solver_wall_s": t.wall_s,
        "speedup": t.wall_s / p.wall_s,
        "solver_warnings": list(b.get("solver_warnings", [])),
    }
    key = readout_key("peak_plate_stress_mpa", a.get("readout", DEFAULT_READOUT))
    if key in a and key != "peak_plate_stress_mpa":  # a derived read-out: its own error, under its own name
        row[key.replace("stress_mpa", "stress_error_pct")] = float(
            100.0 * (a[key] - b["peak_plate_stress_mpa"]) / b["peak_plate_stress_mpa"])
    return row, phys


def verify_designs(preds: list[Prediction], truth: list[Prediction]) -> dict:
    """Per design (added to each prediction's summary under ``verify``, :func:`verify_row`) and summarized over
    designs: the model-vs-solver error of peak plate stress (%), of its location (mm), of maximum deflection (%),
    position RMSE over the window (mm, all nodes and predicted frames), the rise time and the speedup (solver ÷
    prediction wall time); ``physics``: :func:`hcmt.inference.metrics.summarize_impact` of the same rows."""
    rows, physics = [], []
    for p, t in zip(preds, truth):
        row, phys = verify_row(p, t)
        physics.append(phys)
        p.summary["verify"] = row
        p.summary["solver_plate_stress_history_mpa"] = t.summary["plate_stress_history_mpa"]
        rows.append(row)

    def stats(key):
        v = np.array([r[key] for r in rows], np.float64)
        v = np.abs(v) if key.endswith(("pct", "mm", "error")) else v
        v = v[np.isfinite(v)] if np.isfinite(v).any() else v
        return {"median": float(np.median(v)), "max": float(v.max()), "min": float(v.min()), "mean": float(v.mean())}

    keys = ("peak_plate_stress_error_pct", "peak_plate_location_error_mm", "max_deflection_error_pct",
            "position_rmse_mm", "peak_plate_t95_frame_error", "critical_node_history_correlation", "speedup")
    keys += tuple(k for k in rows[0] if k.endswith("_peak_plate_stress_error_pct"))
    return {"designs": len(rows), **{k: stats(k) for k in keys}, "physics": summarize_impact(physics),
            "note": "errors summarized as absolute values (median, max, mean); speedup = solver wall time / "
                    "prediction wall time per design on this machine"}

