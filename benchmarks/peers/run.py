"""hcmt's MGN and HCMT (``official``) against PhysicsNeMo's MeshGraphNet and the authors'
TensorFlow HCMT, on the same graph, one CPU thread each, interleaved.

    benchmarks/peers/install.sh            # the peers' venvs under $HCMT_WORK/peers (skipped when present)
    PYTHONPATH=src python benchmarks/peers/run.py [--rounds 5] [--steps 2] [--peers $HCMT_WORK/peers]
        [--authors $HCMT_WORK/peers/hcmt-tf] [--json benchmarks/results/peers_cpu.json]

``$HCMT_WORK`` is the work folder outside git (default ``benchmarks/work``; docs/RESULTS.md, "Folders").

One graph (:mod:`export_graph`, an .npz every process reads); each contestant is its own process (its own venv)
that builds its model, warms up (compiling, for hcmt's compiled path) and then idles until told to time ``--steps``
train steps or inferences (:mod:`protocol`). Rounds: every contestant in turn (the order rotated each round), train
then inference, so only one computes at a time and load drift on the shared machine hits all alike. Reported per
contestant: the median over rounds of each round's median, and the range of the round medians (the spread); ratios
hcmt ÷ peer are taken within a round (paired) and their median and range reported. GFLOP/s = the FLOPs of a step
(``torch.utils.flop_counter``, matmuls only: see :func:`flops`) ÷ its median time; the core's peak is
:func:`machine.core_peak`."""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
sys.path.insert(0, str(HERE.parent))  # benchmarks/: machine
from machine import core_peak  # noqa: E402

TAG = "@@ "
# (contestant, model family, python (None: this one), worker and its arguments after the graph)
CONTESTANTS = (
    ("hcmt MGN eager", "mgn", None, ["worker_hcmt.py", "{graph}", "mgn", "eager"]),
    ("hcmt MGN compiled", "mgn", None, ["worker_hcmt.py", "{graph}", "mgn", "compiled"]),
    ("PhysicsNeMo MeshGraphNet", "mgn", "physicsnemo", ["worker_physicsnemo.py", "{graph}"]),
    ("hcmt HCMT official eager", "hcmt", None, ["worker_hcmt.py", "{graph}", "hcmt", "eager"]),
    ("hcmt HCMT official compiled", "hcmt", None, ["worker_hcmt.py", "{graph}", "hcmt", "compiled"]),
    ("authors' HCMT (TensorFlow)", "hcmt", "tf", ["worker_tf.py", "{graph}", "{authors}"]),
)
PEER = {"mgn": "PhysicsNeMo MeshGraphNet", "hcmt": "authors' HCMT (TensorFlow)"}
FLOP_SOURCE = {"mgn": "hcmt MGN eager", "hcmt": "hcmt HCMT official eager"}  # the count a contestant without one uses


class Worker:
    """One contestant's process; ``ask`` sends a command and returns its answer."""

    def __init__(self, name: str, argv: list[str], env: dict, log: Path):
        self.name, self.log, self.info = name, log.open("w"), None
        self.proc = subprocess.Popen(
            argv, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self.log, text=True, env=env, cwd=ROOT
        )

    def ready(self, deadline: float) -> None:
        """Wait for the set-up to finish; one that is not done by ``deadline`` (perf_counter) is given up."""
        timer = threading.Timer(max(deadline - time.perf_counter(), 0), self.proc.kill)
        timer.start()
        try:
            self.info = self._read()["ready"]
        except RuntimeError as e:
            raise RuntimeError(f"{e} (set-up overran --ready-s?)" if not timer.is_alive() else str(e)) from None
        finally:
            timer.cancel()
        if self.proc.poll() is not None:  # killed at the deadline just after it said ready
            raise RuntimeError(f"{self.name}: set-up finished at the --ready-s deadline and was stopped")

    def _read(self) -> dict:
        for line in self.proc.stdout:
            if line.startswith(TAG):
                return json.loads(line[len(TAG) :])
            self.log.write(line)
        self.log.flush()
        raise RuntimeError(f"{self.name}: worker ended (exit {self.proc.wait()}); see {self.log.name}")

    def ask(self, cmd: str) -> dict:
        self.proc.stdin.write(cmd + "\n")
        self.proc.stdin.flush()
        return self._read()

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.stdin.write("quit\n")
            self.proc.stdin.close()
            self.proc.wait(timeout=60)
        self.log.close()


def python_of(venv: str | None, peers: Path) -> str:
    return sys.executable if venv is None else str(peers / venv / "bin" / "python")


def start(contestants, graph: Path, peers: Path, authors: Path, logs: Path, ready_s: float) -> tuple[dict, dict]:
    """Every contestant's process, set up side by side (idle ones do not disturb the timing that follows)."""
    env = dict(
        os.environ,
        OMP_NUM_THREADS="1",
        MKL_NUM_THREADS="1",
        TF_USE_LEGACY_KERAS="1",
        TF_CPP_MIN_LOG_LEVEL="2",
        PYTHONPATH=os.pathsep.join([str(ROOT / "src"), str(HERE)]),
    )
    workers, failed = {}, {}
    for name, _, venv, args in contestants:
        python = python_of(venv, peers)
        if not Path(python).is_file():
            failed[name] = f"no interpreter {python}: run benchmarks/peers/install.sh"
            continue
        argv = [python, str(HERE / args[0])] + [a.format(graph=graph, authors=authors) for a in args[1:]]
        workers[name] = Worker(name, argv, env, logs / (re.sub(r"\W+", "_", name) + ".log"))
    t0 = time.perf_counter()
    for name in list(workers):
        try:
            workers[name].ready(t0 + ready_s)
        except RuntimeError as e:
            failed[name] = str(e)
            workers.pop(name).log.close()
            continue
        print(f"{name}: ready after {time.perf_counter() - t0:.0f} s {workers[name].info}", flush=True)
    return workers, failed


def rounds(workers: dict, n_rounds: int, steps: int) -> dict:
    """Per contestant and kind: every round's list of step times (ms)."""
    names = list(workers)
    times = {name: {"train": [], "infer": []} for name in names}
    for r in range(n_rounds):
        order = names[r % len(names) :] + names[: r % len(names)]
        for name in order:
            for kind in ("train", "infer"):
                times[name][kind].append(workers[name].ask(f"{kind} {steps}")["ms"])
        print(
            f"round {r + 1}: "
            + ", ".join(
                f"{n} {statistics.median(times[n]['train'][-1]):.0f}/{statistics.median(times[n]['infer'][-1]):.0f} ms"
                for n in names
            ),
            flush=True,
        )
    return times


def summarize(contestants, workers, times, peak) -> tuple[list, list]:
    rows, ratios = [], []
    family = {name: fam for name, fam, _, _ in contestants}
    info = {name: w.info for name, w in workers.items()}
    for name in workers:
        row = {"contestant": name, "model": family[name], **info[name]}
        for kind in ("train", "infer"):
            med = [statistics.median(t) for t in times[name][kind]]
            row[f"{kind}_ms"] = statistics.median(med)
            row[f"{kind}_ms_rounds"] = med
            source = name if f"flops_{kind}" in info[name] else FLOP_SOURCE[family[name]]
            flops = info.get(source, {}).get(f"flops_{kind}")
            if flops:
                row[f"{kind}_flops"], row[f"{kind}_flops_from"] = flops, source
                row[f"{kind}_gflops_per_s"] = flops / row[f"{kind}_ms"] / 1e6
                row[f"{kind}_peak_share"] = row[f"{kind}_gflops_per_s"] / peak["gflops"]
        rows.append(row)
    for name in workers:
        peer = PEER[family[name]]
        if name == peer or peer not in workers:
            continue
        for kind in ("train", "infer"):
            per_round = [
                statistics.median(a) / statistics.median(b) for a, b in zip(times[name][kind], times[peer][kind])
            ]
            ratios.append(
                {
                    "hcmt": name,
                    "peer": peer,
                    "model": family[name],
                    "kind": kind,
                    "ratio": statistics.median(per_round),
                    "min": min(per_round),
                    "max": max(per_round),
                    "rounds": per_round,
                }
            )
    return rows, ratios


def merged(result: dict, path: Path, families: set, names: set) -> dict:
    """``result`` with the rows, ratios and failures of the other model families kept from ``path`` (a run with
    ``--only mgn`` updates the MGN part; each part's rounds, graph and load are its own, under ``parts``)."""
    old = json.loads(path.read_text()) if path.is_file() else {}
    part = {k: result[k] for k in ("rounds", "steps_per_round", "timed_wall_s", "load_average", "command")}
    result["parts"] = {
        **{f: p for f, p in old.get("parts", {}).items() if f not in families},
        **{f: part for f in families},
    }
    result["rows"] = [r for r in old.get("rows", []) if r["model"] not in families] + result["rows"]
    result["ratios"] = [r for r in old.get("ratios", []) if r.get("model") not in families] + result["ratios"]
    result["failed"] = {**{k: v for k, v in old.get("failed", {}).items() if k not in names}, **result["failed"]}
    return result


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--steps", type=int, default=2, help="timed calls per contestant, kind and round")
    work = Path(os.environ.get("HCMT_WORK") or ROOT / "benchmarks" / "work")
    p.add_argument("--peers", type=Path, default=work / "peers", help="where install.sh put the venvs")
    p.add_argument(
        "--authors",
        type=Path,
        default=work / "peers" / "hcmt-tf",
        help="the authors' code (github.com/yuyudeep/hcmt: core_model.py, model.py, ...)",
    )
    p.add_argument("--only", nargs="+", choices=("mgn", "hcmt"), default=("mgn", "hcmt"))
    p.add_argument(
        "--modes",
        nargs="+",
        choices=("eager", "compiled"),
        default=("eager", "compiled"),
        help="hcmt's paths to time (compiled: minutes of compiling when the inductor cache is cold)",
    )
    p.add_argument("--ready-s", type=float, default=1800, help="give up a worker not set up within this many s")
    p.add_argument("--json", type=Path, default=ROOT / "benchmarks" / "results" / "peers_cpu.json")
    a = p.parse_args(argv)
    contestants = [c for c in CONTESTANTS if c[1] in a.only and (c[2] is not None or c[3][-1] in a.modes)]
    peak = core_peak()
    with tempfile.TemporaryDirectory(prefix="hcmt-peers-") as tmp:
        graph, logs = Path(tmp) / "graph.npz", Path(tmp)
        sys.path.insert(0, str(HERE))
        from export_graph import export

        shape = export(str(graph))
        print(f"graph: {shape}; core peak {peak['gflops']:.0f} GFLOP/s ({peak['derivation']})", flush=True)
        workers, failed = start(contestants, graph, a.peers, a.authors, logs, a.ready_s)
        try:
            t0 = time.perf_counter()
            times = rounds(workers, a.rounds, a.steps)
            wall = time.perf_counter() - t0
        finally:
            for w in workers.values():
                w.close()
            for name in failed:  # keep the failing worker's log in the error
                log = logs / (re.sub(r"\W+", "_", name) + ".log")
                if log.is_file():
                    failed[name] += " | log tail: " + " / ".join(log.read_text().strip().splitlines()[-5:])
    rows, ratios = summarize(contestants, workers, times, peak)
    result = {
        "graph": shape,
        "threads": 1,
        "rounds": a.rounds,
        "steps_per_round": a.steps,
        "timed_wall_s": wall,
        "load_average": list(os.getloadavg()),
        "peak": peak,
        "rows": rows,
        "ratios": ratios,
        "failed": failed,
        "command": "PYTHONPATH=src python benchmarks/peers/run.py " + " ".join(argv or []),
    }
    for r in ratios:
        print(f"{r['hcmt']} / {r['peer']} {r['kind']}: {r['ratio']:.2f} (rounds {r['min']:.2f}-{r['max']:.2f})")
    for name, err in failed.items():
        print(f"FAILED {name}: {err}")
    a.json.parent.mkdir(parents=True, exist_ok=True)
    result = merged(result, a.json, set(a.only), {c[0] for c in contestants})
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # benchmarks/: common
    from common import portable  # noqa: E402  (the work folder as $HCMT_WORK, the checkout as relative)

    a.json.write_text(json.dumps(portable(result), indent=2) + "\n")
    print(f"wrote {a.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
