"""Every GPU number in one time-boxed command, so a GPU lent for minutes yields every GPU number.

    python benchmarks/gpu_check/run.py --out $OUT [--budget-s 480]            # on a GPU machine
    python benchmarks/gpu_check/run.py --smoke --device cpu --out $HCMT_WORK/gc  # the CI rehearsal: toy sizes, < 1 min

Steps, in order of value, each skipped (and named in the summary) when the time left is below its minimum:
cuda tests, train step (HCMT paper / official attention, MGN: eager, compile default, compile reduce-overhead, bf16;
samples/s at batch 8 and 32), inference and learned rollout vs the solver (one design, a batch), memory and time at
64k / 128k / 250k nodes with and without activation checkpointing (stop at the first OOM), a deterministic resume,
and an accuracy mini-study (HCMT and MGN, 2 seeds each, trained concurrently). ``OUT/gpu_check.json`` is rewritten
after every step, so a killed run keeps what finished, and ``--resume`` (the same OUT, its gpu_check.json copied
back) runs only the steps it lacks; a one-screen summary ends the run.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import torch

HERE = Path(__file__).resolve().parent.parent  # benchmarks/: micro, speed
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

from common import portable  # noqa: E402
from hcmt.config import load_config  # noqa: E402
from hcmt.data.runs import RunFolder  # noqa: E402
from hcmt.design.check import check_designs  # noqa: E402
from hcmt.domains.spec import build_for_dataset, dataset_spec  # noqa: E402
from hcmt.files import atomic_path  # noqa: E402
from hcmt.graph.batch import collate  # noqa: E402
from hcmt.graph.build import frame_graph  # noqa: E402
from hcmt.graph.hierarchy import build_hierarchy  # noqa: E402
from hcmt.inference.evaluate import evaluate  # noqa: E402
from hcmt.inference.run import Run  # noqa: E402
from hcmt.sim.generate import generate_dataset  # noqa: E402
from hcmt.sim.mesh import impact_plate_mesh  # noqa: E402
from hcmt.sim.params import Settings  # noqa: E402
from hcmt.sim.sampling import sample_design  # noqa: E402
from hcmt.training import train  # noqa: E402
from micro.bench_models import _step_fn, _sync, impact_plate_graph  # noqa: E402
from speed.run import _one  # noqa: E402


class Check:
    """The JSON record, written after every step."""

    def __init__(self, out: Path, budget: float, smoke: bool, device: str, resume: bool = False):
        self.out, self.budget, self.smoke, self.device = out, budget, smoke, torch.device(device)
        self.start = time.perf_counter()
        name = torch.cuda.get_device_name(self.device) if self.device.type == "cuda" else "cpu"
        self.data = {
            "device": name,
            "torch": torch.__version__,
            "smoke": smoke,
            "budget_s": budget,
            "steps": {},
            "skipped": [],
        }
        if resume and (out / "gpu_check.json").is_file():  # a call cut short (the device's time): keep what finished
            old = json.loads((out / "gpu_check.json").read_text())
            self.data["steps"] = {k: v for k, v in old["steps"].items() if "error" not in v}
            self.data["earlier_calls"] = old.get("earlier_calls", []) + [
                {k: old[k] for k in ("device", "torch", "budget_s") if k in old}
            ]
        out.mkdir(parents=True, exist_ok=True)

    def left(self) -> float:
        return self.budget - (time.perf_counter() - self.start)

    def run(self, name: str, fn, minimum_s: float) -> None:
        if name in self.data["steps"]:  # finished by an earlier call (--resume); each step runs once
            return
        if self.left() < minimum_s:
            self.data["skipped"].append(f"{name} (needs {minimum_s:.0f} s, {self.left():.0f} s left)")
        else:
            t0 = time.perf_counter()
            try:
                result = fn(self)
                self.data["steps"][name] = {"wall_s": time.perf_counter() - t0, **result}
            except Exception as exc:  # a failed step is recorded; the next ones still run
                self.data["steps"][name] = {"wall_s": time.perf_counter() - t0, "error": f"{type(exc).__name__}: {exc}"}
        with atomic_path(self.out / "gpu_check.json") as tmp:
            tmp.write_text(json.dumps(portable(self.data), indent=2, default=str))


def cuda_tests(c: Check) -> dict:
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "-q",
            "-k",
            "cuda",
            "tests/training/test_train.py",
            "tests/models/test_models_invariants.py",
            "-p",
            "no:cacheprovider",
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=max(c.left(), 10),
    )
    lines = [l for l in r.stdout.splitlines() if "passed" in l or "failed" in l or "skipped" in l or "FAILED" in l]
    return {"returncode": r.returncode, "lines": lines[-12:]}


def _timed(fn, device, reps: int, warmup: int) -> float:
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(reps):
        _sync(device)
        t0 = time.perf_counter()
        fn()
        _sync(device)
        times.append(1e3 * (time.perf_counter() - t0))
    return statistics.median(times)


def _graph(c: Check):
    if c.smoke:
        mesh = impact_plate_mesh(0.75, 3.5, 0.4, plate_half_length=8.0)
        h = build_hierarchy(mesh["mesh_pos"], mesh["cells"], mesh["node_type"], levels=2)
        pos = torch.from_numpy(mesh["mesh_pos"]).float()
        feats = torch.cat(
            [torch.nn.functional.one_hot(torch.from_numpy(mesh["node_type"]), 9).float(), torch.randn(len(pos), 4)], 1
        )
        return frame_graph(feats, pos, pos + 0.01 * torch.randn_like(pos), h, 0.4)
    return impact_plate_graph()


def _model(c: Check, name: str, attention: str = "paper"):
    kwargs = {"hidden": 16, "levels": 2, "blocks": 3} if c.smoke else {}
    if name == "hcmt":
        kwargs["attention"] = attention
    if c.smoke and name != "hcmt":
        kwargs.pop("levels")
    torch.manual_seed(0)
    return build_for_dataset(name, "impact_plate", **kwargs).to(c.device)


def train_step(c: Check) -> dict:
    base, rows = _graph(c), []
    out_dim = dataset_spec("impact_plate")["out"]
    reps, warmup = (2, 1) if c.smoke else (20, 5)
    modes = (
        ["eager", "bf16"]
        + ([] if c.smoke else ["compile-default"])
        + (["compile-reduce-overhead"] if c.device.type == "cuda" else [])
    )
    for name, attention in (("hcmt", "paper"), ("hcmt", "official"), ("mgn", "paper")):
        for mode in modes:
            for batch in (1, 8, 32) if mode in ("eager", "bf16") else (1,):
                if c.smoke and batch == 32:
                    continue
                g = collate([base] * batch).to(c.device)
                tgt = torch.randn(g.num_nodes, out_dim, device=c.device)
                model = _model(c, name, attention)
                opt = torch.optim.Adam(model.parameters(), lr=1e-4, fused=c.device.type == "cuda")
                mask = torch.ones(g.num_nodes, 1, device=c.device)
                step, infer = _step_fn(model, g, tgt, opt, mode.startswith("compile"), mask)
                if mode == "bf16":
                    plain = step

                    def step():
                        with torch.autocast(c.device.type, dtype=torch.bfloat16):
                            plain()

                ms = _timed(step, c.device, reps, warmup)
                row = {
                    "model": f"{name}-{attention}" if name == "hcmt" else name,
                    "mode": mode,
                    "batch": batch,
                    "nodes": g.num_nodes,
                    "train_ms": ms,
                    "samples_per_s": 1e3 * batch / ms,
                }
                if batch == 1:
                    row["inference_ms"] = _timed(infer, c.device, reps, warmup)
                rows.append(row)
                if c.left() < 30:
                    return {"rows": rows, "stopped": "time"}
    return {"rows": rows}


def rollout_vs_solver(c: Check) -> dict:

    run = Run.load("pretrained:impact_plate_small", str(c.device))
    rng = np.random.default_rng(7)
    n = 2 if c.smoke else 64
    designs = [(f"d{i}", sample_design(rng, "small")) for i in range(n)]
    one = check_designs(run, designs[:1], batch=1, verify=True, progress=False)
    many = check_designs(run, designs, batch=n, progress=False)
    # the solver's median from the first few designs: solving all 64 serially on the CPU outran the whole budget
    solved = check_designs(run, designs[:SOLVER_DESIGNS], batch=SOLVER_DESIGNS, verify=True, progress=False)
    solver = one.truth[0].wall_s
    out = {
        "one_design_s": one.preds[0].wall_s,
        "solver_one_design_s": solver,
        "speedup_one": solver / one.preds[0].wall_s,
        "batch": n,
        "batch_per_design_s": many.preds[0].wall_s,
        "solver": f"built-in FEM, one CPU core per design, {one.verified.speedup_measured.solver}",
        "solver_designs": len(solved.truth),
        "solver_median_s": float(np.median([t.wall_s for t in solved.truth])),
    }
    out["speedup_batch"] = out["solver_median_s"] / many.preds[0].wall_s
    if not c.smoke and c.left() > 240:  # the forward compiled ahead of time (--compile aot): built once, then loaded
        t0 = time.perf_counter()
        check_designs(run, designs[:1], batch=1, compile="aot", progress=False)
        out["aot_first_call_s"] = time.perf_counter() - t0  # the package built (or loaded) and one design
        aot = check_designs(run, designs[:1], batch=1, compile="aot", progress=False)
        out["one_design_aot_s"] = aot.preds[0].wall_s
        out["speedup_one_aot"] = solver / aot.preds[0].wall_s
    return out


SOLVER_DESIGNS = 4  # designs the solver runs for its median time per design


def memory(c: Check) -> dict:
    rows = []
    for nodes in (1500,) if c.smoke else (64000, 128000, 250000):
        for ckpt in (False, True):
            try:
                rows.append(_one("hcmt", nodes, 1 if c.smoke else 3, ckpt, str(c.device)))
            except (torch.cuda.OutOfMemoryError, MemoryError) as exc:
                rows.append({"nodes": nodes, "checkpoint_blocks": ckpt, "oom": str(exc)[:200]})
                return {"rows": rows, "stopped": "first OOM"}
            finally:
                if c.device.type == "cuda":
                    torch.cuda.empty_cache()
                    torch.cuda.reset_peak_memory_stats(c.device)
    return {"rows": rows}


def _generate(c: Check, out: Path) -> Path:
    data = out / "data"
    if not (data / "test.h5").is_file():  # the generator resumes where it stopped
        counts, frames = (dict(train=2, valid=1, test=1), 6) if c.smoke else (dict(train=128, valid=8, test=16), 90)
        generate_dataset(
            data,
            preset="small",
            counts=counts,
            seed=5,
            workers=max(os.cpu_count() or 1, 1),
            settings=Settings(frames=frames),
            progress=False,
        )
    return data


def _overrides(c: Check) -> list[str]:
    """The config overrides of this check's training runs (a tiny model for the smoke run)."""
    size = (
        ["model.hidden=16", "model.levels=1", "model.L_C=1", "model.blocks=3", "train.normalizer_steps=1"]
        if c.smoke
        else ["model.hidden=128"]
    )
    return ["train.valid_every=0", *size]


def _train_args(c: Check, data: Path, model: str, seed: int, out: Path, steps: int, extra=()) -> list[str]:
    """``hcmt train`` in its own process (the accuracy runs train four at once on the one device)."""
    sets = [a for o in [*_overrides(c), *extra] for a in ("--set", o)]
    return [
        sys.executable,
        "-m",
        "hcmt",
        "train",
        "--config",
        "impact_plate_cpu",
        "--data",
        str(data),
        "--model",
        model,
        "--seed",
        str(seed),
        "--steps",
        str(steps),
        "--out",
        str(out),
        "--device",
        str(c.device),
        "--no-progress",
        "--threads",
        "1",
        *sets,
    ]


def deterministic_resume(c: Check) -> dict:
    """A run stopped half-way and resumed ends with the parameters of one that never stopped
    (``train.deterministic``: exact on CUDA too)."""

    data = _generate(c, c.out / "mini")
    steps = 4 if c.smoke else 40
    cfg = load_config(
        "impact_plate_cpu",
        _overrides(c) + [f"train.steps={steps}", "train.deterministic=true", f"train.checkpoint_every={steps // 2}"],
    )
    once, twice = c.out / "det_once", c.out / "det_twice"
    for run in (once, twice):
        if run.exists():
            shutil.rmtree(run)
    train(cfg, data, "hcmt", once, device=str(c.device), progress=False)
    train(cfg, data, "hcmt", twice, device=str(c.device), progress=False, stop_at=steps // 2)
    train(cfg, data, "hcmt", twice, device=str(c.device), progress=False, resume=True)
    a = torch.load(RunFolder(once).latest, weights_only=True)["model"]
    b = torch.load(RunFolder(twice).latest, weights_only=True)["model"]
    diff = max(float((a[k].float() - b[k].float()).abs().max()) for k in a)
    return {"steps": steps, "max_abs_difference": diff, "exact": diff == 0.0}


def accuracy(c: Check) -> dict:
    data = _generate(c, c.out / "mini")
    # steps fitted to the time left: ~60 % of it for training, four runs at once on the one device
    per_step = 0.02 if c.device.type == "cuda" else 0.05
    steps = 3 if c.smoke else max(200, int(0.6 * c.left() / per_step / 2))
    procs, runs = [], []
    for model in ("hcmt", "mgn"):
        for seed in (0, 1):
            out = c.out / f"acc_{model}_s{seed}"
            extra = ["model.attention=official"] if model == "hcmt" else []
            procs.append(
                subprocess.Popen(
                    _train_args(c, data, model, seed, out, steps, extra),
                    stdout=subprocess.DEVNULL,
                    stderr=subprocess.DEVNULL,
                )
            )
            runs.append((model, seed, out))
    for p in procs:
        p.wait(timeout=max(c.left(), 10))

    rows = []
    for model, seed, out in runs:
        m = evaluate(Run.load(out, str(c.device)), data, "test", batch=16, progress=False)
        rows.append(
            {
                "model": model,
                "seed": seed,
                "position_rmse_all": m.position.rmse_all,
                "stress_rmse_all": m.stress.rmse_all,
                "physics": None if m.physics is None else m.physics.to_json(),
            }
        )
    mean = {k: statistics.mean(r["position_rmse_all"] for r in rows if r["model"] == k) for k in ("hcmt", "mgn")}
    return {"steps": steps, "rows": rows, "hcmt_over_mgn_position": mean["hcmt"] / mean["mgn"]}


STEPS = [
    ("cuda tests", cuda_tests, 20),
    ("train step", train_step, 30),
    ("rollout vs solver", rollout_vs_solver, 20),
    ("memory", memory, 30),
    ("deterministic resume", deterministic_resume, 20),
    ("accuracy", accuracy, 240),
]


def summary(data: dict) -> str:
    lines = [f"gpu_check on {data['device']} (torch {data['torch']}{', smoke' if data['smoke'] else ''})"]
    for name, r in data["steps"].items():
        if "error" in r:
            lines.append(f"  {name}: ERROR {r['error']}")
        elif name == "train step":
            best = {}
            for row in r["rows"]:
                if row["batch"] == 1:
                    best.setdefault(row["model"], []).append(f"{row['mode']} {row['train_ms']:.1f} ms")
            lines += [f"  train step {k}: " + ", ".join(v) for k, v in best.items()]
        else:
            lines.append(
                f"  {name}: "
                + ", ".join(
                    f"{k} {v:.3g}" if isinstance(v, float) else f"{k} {v}"
                    for k, v in r.items()
                    if not isinstance(v, (list, dict))
                )
            )
    lines += [f"  skipped: {s}" for s in data["skipped"]]
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, required=True, help="folder of gpu_check.json and the mini-study's runs")
    p.add_argument("--budget-s", type=float, default=480.0)
    p.add_argument("--device", default="cuda")
    p.add_argument("--smoke", action="store_true", help="toy sizes (the CI rehearsal; with --device cpu)")
    p.add_argument(
        "--resume",
        action="store_true",
        help="keep the steps OUT/gpu_check.json already holds without an error; run only the others",
    )
    a = p.parse_args(argv)
    if torch.device(a.device).type == "cuda" and not torch.cuda.is_available():
        print(
            "gpu_check: error: no CUDA device here; on a CPU machine run the rehearsal: --smoke --device cpu",
            file=sys.stderr,
        )
        return 2
    if torch.device(a.device).type == "cpu" and not a.smoke:
        print("gpu_check: error: --device cpu is for the rehearsal only (add --smoke)", file=sys.stderr)
        return 2
    c = Check(a.out, a.budget_s, a.smoke, a.device, a.resume)
    for name, fn, minimum in STEPS:
        c.run(name, fn, minimum * (0.1 if a.smoke else 1.0))
    print(summary(c.data))
    return 0


if __name__ == "__main__":
    sys.exit(main())
