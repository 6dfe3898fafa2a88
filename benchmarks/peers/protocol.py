"""The worker side of the interleaved timing (standard library only: every peer's venv imports it).

A worker builds its model, warms it up, prints ``@@ {"ready": info}`` and then answers each stdin line
``train N`` / ``infer N`` with ``@@ {"ms": [...]}`` (the N steps' wall times), ``quit`` ends it. Only lines that
start with ``@@`` belong to the protocol, so a library's own prints on stdout do no harm."""

from __future__ import annotations

import json
import os
import sys
import time

TAG = "@@ "


def one_thread() -> None:
    """One thread for every math library the worker may load (set before they are imported)."""
    for var in (
        "OMP_NUM_THREADS",
        "MKL_NUM_THREADS",
        "OPENBLAS_NUM_THREADS",
        "TF_NUM_INTRAOP_THREADS",
        "TF_NUM_INTEROP_THREADS",
    ):
        os.environ[var] = "1"


def say(obj) -> None:
    print(TAG + json.dumps(obj), flush=True)


def serve(train, infer, info: dict) -> None:
    """Answer the orchestrator's commands with ``train()`` / ``infer()`` timed one call at a time."""
    fns = {"train": train, "infer": infer}
    say({"ready": info})
    for line in sys.stdin:
        cmd = line.split()
        if not cmd or cmd[0] == "quit":
            break
        fn, times = fns[cmd[0]], []
        for _ in range(int(cmd[1])):
            t0 = time.perf_counter()
            fn()
            times.append(1000 * (time.perf_counter() - t0))
        say({"ms": times})


def warm(fn, n: int) -> float:
    """Seconds for ``n`` first calls (tracing / compiling included)."""
    t0 = time.perf_counter()
    for _ in range(n):
        fn()
    return time.perf_counter() - t0


def warm_up(info: dict, train, infer, flop_counter=None) -> dict:
    """Every worker's start, recorded in ``info`` (returned): ``warmup_train_s`` and ``warmup_infer_s``, the seconds
    of the first 3 training steps and 2 inferences (tracing / compiling included); with ``flop_counter`` (a callable
    giving a context manager with ``get_total_flops()``, e.g. ``lambda: FlopCounterMode(display=False)``), the
    FLOPs of one more call of each, ``flops_train`` and ``flops_infer``."""
    info["warmup_train_s"] = warm(train, 3)
    info["warmup_infer_s"] = warm(infer, 2)
    for kind, fn in (("train", train), ("infer", infer)) if flop_counter is not None else ():
        with flop_counter() as fc:
            fn()
        info[f"flops_{kind}"] = fc.get_total_flops()
    return info
