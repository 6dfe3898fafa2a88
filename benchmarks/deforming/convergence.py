"""Mesh convergence of the Deforming Plate's peak stress (docs/solver.md, "Deforming Plate: mesh convergence").

    OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/deforming/convergence.py [--frames 41]

The nominal design (100 x 55 x 5 mm plate, E 20 MPa, ν 0.35, a sphere of radius 10 mm pressed 12.5 mm down at
x = 0.7 L) at refining meshes (layers through the thickness, plate nodes): the last frame's peak nodal von Mises
stress, the actuator force and the free end's deflection. The press path is monotonic and the material
hyperelastic, so the last frame does not depend on the number of load steps. Writes
benchmarks/results/deforming_convergence.json. Cost: a few minutes (the finest mesh dominates).
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # benchmarks/: common
from common import write_json  # noqa: E402
from hcmt.sim.deforming import solve_plate  # noqa: E402
from hcmt.sim.plate_params import PlateDesign, PlateSettings  # noqa: E402

MESHES = ((2, 300), (3, 1100), (4, 2600), (5, 5000))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--frames", type=int, default=41)
    a = p.parse_args()
    rows = []
    for layers, nodes in MESHES:
        start = time.process_time()
        r = solve_plate(PlateDesign(), PlateSettings(frames=a.frames, plate_nodes=nodes, layers=layers))
        pos = r["scene"].body.pos
        end = pos[:, 0] == pos[:, 0].max()
        rows.append(
            {
                "layers": layers,
                "plate_nodes": len(pos),
                "spacing_mm": round(r["scene"].spacing, 3),
                "peak_von_mises_MPa": round(float(r["von_mises"][-1].max()), 4),
                "actuator_force_N": round(float(r["actuator_force"][-1, 2]), 4),
                "end_deflection_mm": round(float(-(r["world"][-1, end, 2] - pos[end, 2]).mean()), 4),
                "cpu_s": round(time.process_time() - start, 1),
            }
        )
        print(rows[-1], flush=True)
    write_json(
        "deforming_convergence.json",
        {
            "frames": a.frames,
            "rows": rows,
            "command": "OMP_NUM_THREADS=1 PYTHONPATH=src python "
            f"benchmarks/deforming/convergence.py --frames {a.frames}",
        },
    )


if __name__ == "__main__":
    main()
