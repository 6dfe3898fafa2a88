"""Does the recorded window hold the whole impact? The solver on the corners of the `small` preset's ranges
(thickness 0.5-1.0 mm, drop height 500-1,000 mm, ball radius 3.5 and 4.25 mm; other parameters at mid-range),
101 frames of 0.002 ms: the frame of the plate's peak stress, of the ball's rebound (vertical velocity > 0) and
of the maximum deflection, and how far the peak within 52 frames (the old window) falls below the true one.

    python benchmarks/recipe/window.py          # writes benchmarks/results/window.json
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # benchmarks/: common
from common import write_json  # noqa: E402
from hcmt.inference.quantities import body_history, deflection, peak, plate_mask  # noqa: E402
from hcmt.sim.driver import simulate  # noqa: E402
from hcmt.sim.params import Design, Settings  # noqa: E402
from hcmt.sim.sampling import RANGES  # noqa: E402

CORNERS = [(0.5, 500), (0.5, 1000), (0.6, 1000), (0.75, 750), (1.0, 1000), (1.0, 500)]


def main() -> None:
    torch.set_num_threads(1)
    mid = {k: (a + b) / 2 for k, (a, b) in RANGES["small"].items()}
    rows = []
    for th, height in CORNERS:
        for radius in (3.5, 4.25):
            d = Design(**{**mid, "thickness": th, "drop_height": height, "ball_radius": radius})
            f = simulate(d, Settings(frames=101)).fields
            w = f["world_pos"]
            plate = plate_mask(f["cells"], f["node_type"])
            value, frame, _ = peak(f["stress"], plate)
            vy = w[1:, ~plate, 1].mean(1) - w[:-1, ~plate, 1].mean(1)
            up = np.flatnonzero(vy > 0)
            defl = np.abs(deflection(w, f["mesh_pos"], plate)).max(1)
            rows.append(
                {
                    "thickness": th,
                    "drop_height": height,
                    "ball_radius": radius,
                    "peak_frame": frame,
                    "peak_mpa": value,
                    "peak_within_52_mpa": float(body_history(f["stress"], plate)[:52].max()),
                    "rebound_frame": int(up[0]) if len(up) else None,
                    "max_deflection_frame": int(defl.argmax()),
                }
            )
            print(rows[-1], flush=True)
    write_json(
        "window.json",
        {"frames": 101, "frame_dt_ms": 0.002, "designs": rows, "command": "python benchmarks/recipe/window.py"},
    )


if __name__ == "__main__":
    main()
