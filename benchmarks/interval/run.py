"""The frame-interval study: accuracy and speed of HCMT and MGN against the frame interval, at CPU scale.

The same 40 / 4 / 12 designs of the `small` preset (seed 2026) are recorded over the same 0.176 ms window at
0.002, 0.004 and 0.008 ms (89, 45 and 23 frames; `hcmt generate --frame-dt`). Per interval and formulation
(today's: velocity target, noise on NORMAL nodes; the recipe study's choice: acceleration target, noise on the
predicted nodes, pushforward from a third of the steps, edge deformation features), three models at equal steps:
HCMT (official attention), MGN (11 blocks, as many as HCMT has) and MGN with twice the blocks (22: the depth
control). The training noise σ is chosen per model, interval and formulation on the validation split: seed 0 is
trained at each of the candidates (3e-4 and 1e-3 mm at 0.002 ms, scaled with the interval like the per-frame
motion) and the lowest validation position RMSE-all wins; seeds 1 and 2 then train at that σ. Resumable; several
processes may share the work (run locks).

    python benchmarks/interval/run.py --work $HCMT_WORK/interval [--steps 1000]   # data + training + evaluation
    python benchmarks/interval/run.py --work $HCMT_WORK/interval --peaks          # recorded vs true peak stress
    python benchmarks/interval/run.py --work $HCMT_WORK/interval --speed          # design check per interval
    python benchmarks/interval/run.py --work $HCMT_WORK/interval --table-only     # results/interval.json + figure
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # benchmarks/: common
from common import RESULTS, dataset, run_and_evaluate, write_json  # noqa: E402
from hcmt.data.format import Split  # noqa: E402
from hcmt.design.check import check_designs  # noqa: E402
from hcmt.inference.metrics import mean_std  # noqa: E402
from hcmt.inference.run import Run  # noqa: E402
from hcmt.sim.params import DESIGN_KEYS, Design  # noqa: E402
from parity.propagation import hcmt_reach, trajectory_numbers  # noqa: E402

WINDOW_FRAMES = {0.002: 89, 0.004: 45, 0.008: 23}  # 88 x 0.002 = 44 x 0.004 = 22 x 0.008 = 0.176 ms
DATA = dict(preset="small", train=40, valid=4, test=12, seed=2026, variants=0)
CONFIG = "impact_plate_cpu"
#: label -> (model name, overrides)
MODELS = {"hcmt": ("hcmt", ["model.attention=official"]), "mgn": ("mgn", []), "mgn-deep": ("mgn", ["model.blocks=22"])}
SIGMAS = (3e-4, 1e-3)  # candidates at 0.002 ms (mm), scaled with the interval
SEEDS = (0, 1, 2)


def forms(steps: int) -> dict[str, list[str]]:
    """label -> overrides of the two formulations (pushforward from a third of the steps, as in the recipe
    study)."""
    return {
        "today": [],
        "recipe": [
            "model.target=acceleration",
            "train.noise_nodes=predicted",
            "train.pushforward=0.5",
            f"train.pushforward_start={steps // 3}",
            "model.deformation=true",
        ],
    }


def data_spec(dt: float) -> dict:
    return dict(DATA, frames=WINDOW_FRAMES[dt], frame_dt=dt)


def sigma_of(dt: float, base: float) -> float:
    return float(f"{base * dt / 0.002:.3g}")


def run_name(dt: float, form: str, model: str, seed: int, sigma: float, steps: int) -> str:
    return f"int_{dt:g}_{form}_{model}_s{seed}_n{sigma:g}_{steps}"


def configs(steps: int):
    for dt in WINDOW_FRAMES:
        for form in forms(steps):
            for model in MODELS:
                yield dt, form, model


def overrides(dt, form, model, sigma, steps) -> list[str]:
    return [f"train.steps={steps}", f"train.noise_std={sigma}", *MODELS[model][1], *forms(steps)[form]]


def valid_rmse(run: Path) -> float | None:
    f = run / "metrics_valid.json"
    return json.loads(f.read_text())["position"]["rmse_all"] if f.is_file() else None


def chosen_sigma(work: Path, dt, form, model, steps) -> float | None:
    """The candidate σ with the lowest validation position RMSE-all of seed 0; None until every candidate ran."""
    scores = {}
    for base in SIGMAS:
        s = sigma_of(dt, base)
        scores[s] = valid_rmse(work / "runs" / run_name(dt, form, model, 0, s, steps))
    if any(v is None for v in scores.values()):
        return None
    return min(scores, key=scores.get)


def train_all(work: Path, steps: int, datasets: dict[float, Path]) -> None:
    def one(dt, form, model, seed, sigma, splits):
        name = run_name(dt, form, model, seed, sigma, steps)
        print(f"{name}", flush=True)
        return run_and_evaluate(
            work,
            datasets[dt],
            name,
            MODELS[model][0],
            seed,
            overrides(dt, form, model, sigma, steps),
            splits=splits,
            config=CONFIG,
        )

    for dt, form, model in configs(steps):  # 1. seed 0 at every σ candidate (validation split: the choice)
        for base in SIGMAS:
            one(dt, form, model, 0, sigma_of(dt, base), ("valid",))
    while True:  # 2. the chosen σ: seed 0 on the test split, seeds 1 and 2 (waits for the other process's runs)
        pending = False
        for seed in SEEDS:
            for dt, form, model in configs(steps):
                sigma = chosen_sigma(work, dt, form, model, steps)
                if sigma is None or one(dt, form, model, seed, sigma, ("valid", "test")) is None:
                    pending = True
        if not pending:
            return
        time.sleep(30)


# -- propagation per interval ---------------------------------------------------------------------------------------
def propagation(datasets: dict[float, Path], limit: int = 12) -> dict:
    """Stress-front and P-wave hops per frame of each interval's test designs (benchmarks/parity/propagation.py) against
    each model's hops per step: MGN one per block (11; deep 22), HCMT L_C + its hierarchy's spans."""
    out = {}
    for dt, path in datasets.items():
        with Split(path, "test") as s:
            rows = [trajectory_numbers(s[i], s.attrs(i), dt) for i in range(min(limit, len(s)))]
            reach = hcmt_reach(s[0], levels=4, L_C=2)
        # the front reaches the clamp within a frame or two at coarse intervals: its hops per frame is then the
        # clamp distance over the frames it took (a lower bound), from frame 1 (the ball is released at frame 0)
        front = [r["front_hops_per_frame"] if r["front_hops_per_frame"] > 0 else np.nan for r in rows]
        out[f"{dt:g}"] = {
            "trajectories": len(rows),
            "front_hops_per_frame": float(np.nanmedian(front)),
            "p_wave_hops_per_frame": float(np.median([r["p_wave_hops_per_frame"] for r in rows])),
            "frames_to_reach_clamp": float(np.median([r["frames_to_reach_clamp"] or np.nan for r in rows])),
            "impact_to_clamp_hops": float(np.median([r["impact_to_clamp_hops"] for r in rows])),
            "reach_per_step": {"mgn": 11, "mgn-deep": 22, "hcmt": reach["hops_per_step"]},
        }
    return out


# -- the tables -------------------------------------------------------------------------------------------------------
KEYS = {
    "position_rmse_all": lambda m: m["position"]["rmse_all"],
    "stress_rmse_all": lambda m: m["stress"]["rmse_all"],
    "rebound_agreement": lambda m: m["physics"]["rebound_agreement"],
    "peak_plate_stress_error_pct": lambda m: m["physics"]["peak_plate_stress_error_pct"]["median_abs"],
    "peak_plate_stress_error_pct_signed": lambda m: m["physics"]["peak_plate_stress_error_pct"]["median"],
    "max_deflection_error_pct": lambda m: m["physics"]["max_deflection_error_pct"]["median_abs"],
    "peak_plate_frame_error": lambda m: m["physics"]["peak_plate_frame_error"]["median_abs"],
    "far_deflection_error_um": lambda m: m["physics"]["far_deflection_error_um"]["median"],
    "inference_ms_per_step": lambda m: m["inference_ms_per_step"],
    "train_ms_per_step": lambda m: m["train_ms_per_step"],
}


def cell(work: Path, dt, form, model, steps, split="test") -> dict | None:
    """Mean ± std over the seeds trained at the chosen σ (None until one has finished)."""
    sigma = chosen_sigma(work, dt, form, model, steps)
    if sigma is None:
        return None
    ms = []
    for seed in SEEDS:
        f = work / "runs" / run_name(dt, form, model, seed, sigma, steps) / f"metrics_{split}.json"
        if f.is_file():
            ms.append(json.loads(f.read_text()))
    if not ms:
        return None
    row = {"sigma_mm": sigma, "seeds": len(ms), **{k: mean_std(get(m) for m in ms) for k, get in KEYS.items()}}
    row["peak_time_error_ms"] = {k: v * dt for k, v in row["peak_plate_frame_error"].items() if k != "n"}
    row["model_steps_per_design"] = WINDOW_FRAMES[dt] - 2
    return row


def ratio(a: dict, b: dict, key: str) -> dict:
    """a ÷ b of the seed means, and whether the two are separated: at least two seeds each and the means further
    apart than the larger std over seeds (one seed separates nothing)."""
    ma, mb = a[key]["mean"], b[key]["mean"]
    enough = min(a["seeds"], b["seeds"]) >= 2
    return {"ratio": ma / mb, "separated": enough and abs(ma - mb) > max(a[key]["std"], b[key]["std"])}


def table(work: Path, steps: int, datasets: dict[float, Path]) -> dict:
    rows: dict = {}
    for dt, form, model in configs(steps):
        c = cell(work, dt, form, model, steps)
        if c is not None:
            rows.setdefault(f"{dt:g}", {}).setdefault(form, {})[model] = c
    for dt_key, forms_ in rows.items():
        for form, models in forms_.items():
            if "hcmt" in models:
                models["ratios"] = {
                    f"hcmt/{other}": {
                        k: ratio(models["hcmt"], models[other], k) for k in ("position_rmse_all", "stress_rmse_all")
                    }
                    for other in ("mgn", "mgn-deep")
                    if other in models
                }
    sigma_sweep = {}
    for dt, form, model in configs(steps):
        sigma_sweep.setdefault(f"{dt:g}", {}).setdefault(form, {})[model] = {
            f"{sigma_of(dt, b):g}": valid_rmse(work / "runs" / run_name(dt, form, model, 0, sigma_of(dt, b), steps))
            for b in SIGMAS
        }
    out = {
        "data": {f"{dt:g}": data_spec(dt) for dt in WINDOW_FRAMES},
        "config": CONFIG,
        "steps": steps,
        "models": {k: v[1] for k, v in MODELS.items()},
        "formulations": forms(steps),
        "seeds": list(SEEDS),
        "sigma_candidates_at_0.002": list(SIGMAS),
        "valid_position_rmse_by_sigma": sigma_sweep,
        "propagation": propagation(datasets),
        "table": rows,
    }
    prev = RESULTS / "interval.json"
    if prev.is_file():  # keep the speed and peak sections of an earlier --speed / --peaks run
        old = json.loads(prev.read_text())
        out.update({k: old[k] for k in ("speed",) if k in old})
    write_json("interval.json", out)
    figure(out)
    return out


def figure(out: dict) -> Path:
    """HCMT ÷ MGN (and ÷ deep MGN) RMSE-all against the stress front's hops per frame ÷ the baseline's reach."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4), constrained_layout=True)
    for ax, q in zip(axes, ("position_rmse_all", "stress_rmse_all")):
        for form, style in (("today", "o-"), ("recipe", "s--")):
            for other, colour in (("mgn", "C0"), ("mgn-deep", "C1")):
                xs, ys = [], []
                for dt_key, forms_ in out["table"].items():
                    models = forms_.get(form, {})
                    if f"hcmt/{other}" not in models.get("ratios", {}):
                        continue
                    prop = out["propagation"][dt_key]
                    xs.append(prop["front_hops_per_frame"] / prop["reach_per_step"][other])
                    ys.append(models["ratios"][f"hcmt/{other}"][q]["ratio"])
                if xs:
                    order = np.argsort(xs)
                    ax.plot(
                        np.array(xs)[order],
                        np.array(ys)[order],
                        style,
                        color=colour,
                        label=f"HCMT ÷ {other.upper().replace('-DEEP', ' (22 blocks)')}, {form}",
                    )
        ax.axhline(1.0, color="grey", lw=0.8)
        ax.axvline(1.0, color="grey", lw=0.8, ls=":")
        ax.set_xlabel("stress-front hops per frame ÷ the baseline's hops per step")
        ax.set_ylabel("HCMT ÷ baseline, RMSE-all (test, 3 seeds)")
        ax.set_title(q.split("_")[0])
        ax.legend(fontsize=7)
    path = Path(__file__).resolve().parents[2] / "docs" / "img" / "interval_ratio.png"
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=130)
    return path


# -- speed: the design check at each interval ---------------------------------------------------------------------
def speed(work: Path, steps: int, datasets: dict[float, Path], form: str = "recipe") -> dict:
    """``predict --verify`` of the 12 test designs with each interval's HCMT (seed 0, chosen σ): learned and solver
    wall time per design, one design at a time and all 12 in one batch, on this machine (one thread)."""
    out = {}
    for dt, path in datasets.items():
        sigma = chosen_sigma(work, dt, form, "hcmt", steps)
        run = Run.load(work / "runs" / run_name(dt, form, "hcmt", 0, sigma, steps), "cpu")
        with Split(path, "test") as s:
            designs = [
                (s.names[i], Design(**{k: v for k, v in s.attrs(i).items() if k in DESIGN_KEYS})) for i in range(len(s))
            ]
        one = check_designs(run, designs, batch=1, verify=True, progress=False)
        batched = check_designs(run, designs, batch=len(designs), verify=False, progress=False)
        learned_one = [p.wall_s for p in one.preds]
        solver = [t.wall_s for t in one.truth]
        out[f"{dt:g}"] = {
            "run": run.source,
            "designs": len(designs),
            "frames": WINDOW_FRAMES[dt],
            "learned_s_per_design_one_at_a_time": float(np.median(learned_one)),
            "learned_s_per_design_batched": batched.wall_s / len(designs),
            "solver_s_per_design": float(np.median(solver)),
            "speedup_one_at_a_time": float(np.median(solver) / np.median(learned_one)),
            "speedup_batched": float(np.median(solver) / (batched.wall_s / len(designs))),
            "verify": {
                k: getattr(one.verified, k).to_json()
                for k in ("peak_plate_stress_error_pct", "max_deflection_error_pct")
            },
        }
        print(
            f"{dt:g} ms: learned {out[f'{dt:g}']['learned_s_per_design_one_at_a_time']:.3f} s/design (batched "
            f"{out[f'{dt:g}']['learned_s_per_design_batched']:.3f}), solver {np.median(solver):.3f} s",
            flush=True,
        )
    out["device"] = f"cpu ({platform.processor() or platform.machine()}), 1 thread"
    prev = RESULTS / "interval.json"
    data = json.loads(prev.read_text()) if prev.is_file() else {}
    data["speed"] = out
    write_json("interval.json", data)
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--work", type=Path, default=Path("benchmarks/work"))
    p.add_argument("--steps", type=int, default=1000)
    p.add_argument(
        "--table-only", action="store_true", help="write results/interval.json and the figure; train nothing"
    )
    p.add_argument("--speed", action="store_true", help="the design check at each interval (after training)")
    a = p.parse_args()
    datasets = {dt: dataset(a.work, data_spec(dt)) for dt in WINDOW_FRAMES}
    if a.speed:
        speed(a.work, a.steps, datasets)
    elif not a.table_only:
        train_all(a.work, a.steps, datasets)
    table(a.work, a.steps, datasets)
    print(f"wrote {RESULTS / 'interval.json'}")


if __name__ == "__main__":
    main()
