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
    for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "TF_NUM_INTRAOP_THREADS",
                "TF_NUM_INTEROP_THREADS"):
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
