"""--threads: the design check's wall time with another CPU-bound job on the machine, one thread, the old default
(torch's, all cores) and `auto` (cores minus the load average), for one design and a batch of 8.

    python benchmarks/speed/threads.py         # writes benchmarks/results/threads.json

Each setting runs `hcmt predict pretrained:impact_plate_small` in a fresh process while a busy loop holds one core
(after 70 s of warm-up, so the 1-minute load average sees it); the median of 3 runs per setting is reported.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # benchmarks/: common
from common import write_json  # noqa: E402

DESIGNS = {
    1: ["--design", "thickness=0.7"],
    8: [x for t in (0.55, 0.6, 0.65, 0.7, 0.75, 0.8, 0.85, 0.9) for x in ("--design", f"thickness={t}")],
}


def wall(threads: str, designs: list[str]) -> float:
    t0 = time.perf_counter()
    cmd = [
        sys.executable,
        "-m",
        "hcmt",
        "predict",
        "pretrained:impact_plate_small",
        *designs,
        "--batch",
        "8",
        "--no-progress",
        "--device",
        "cpu",
        "--threads",
        threads,
    ]
    subprocess.run(cmd, check=True, capture_output=True)
    return time.perf_counter() - t0


def main() -> None:
    busy = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        time.sleep(70)
        rows = {}
        for n, designs in DESIGNS.items():
            for threads in ("1", "auto", str(os.cpu_count())):  # all cores: torch's default before --threads
                times = [wall(threads, designs) for _ in range(3)]
                rows[f"{n} design(s), --threads {threads}"] = {"median_s": float(np.median(times)), "runs": times}
                print(f"{n} design(s), threads {threads}: {np.median(times):.2f} s", flush=True)
    finally:
        busy.kill()
    write_json(
        "threads.json",
        {
            "cores": os.cpu_count(),
            "other_job": "one busy Python loop",
            "results": rows,
            "note": f"--threads {os.cpu_count()} is torch's default, what hcmt did before "
            "--threads existed; no option is now auto",
            "command": "python benchmarks/speed/threads.py",
        },
    )


if __name__ == "__main__":
    main()
