"""The peak plate stress and deflection of one plate as the mesh refines (docs/solver.md, "Panel families").

    python benchmarks/interval/peak_convergence.py [--sizes 0.3 0.2 0.15]

A 0.9 mm glass plate of the small preset (radius 12 mm, ball 3.75 mm, 750 mm drop, 45 frames): the nodal peak
under the ball at each mesh size beside the deflection. Writes benchmarks/results/peak_convergence.json.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # benchmarks/: common
from common import write_json  # noqa: E402
from hcmt.inference.quantities import max_deflection, peak, plate_mask  # noqa: E402
from hcmt.sim.driver import simulate  # noqa: E402
from hcmt.sim.params import Design, Settings  # noqa: E402


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizes", nargs="+", type=float, default=[0.3, 0.2, 0.15])
    a = p.parse_args()
    rows = []
    for h in a.sizes:
        r = simulate(Design(thickness=0.9, mesh_size=h, ball_radius=3.75, plate_half_length=12.0), Settings(frames=45))
        f = r.fields
        plate = plate_mask(f["cells"], f["node_type"])
        rows.append(
            {
                "mesh_size": h,
                "nodes": r.info.num_nodes,
                "peak_plate_stress_mpa": peak(f["stress"], plate)[0],
                "max_deflection_mm": max_deflection(f["world_pos"], f["mesh_pos"], plate),
            }
        )
        print(rows[-1], flush=True)
    write_json(
        "peak_convergence.json",
        {
            "command": "python benchmarks/interval/peak_convergence.py --sizes " + " ".join(map(str, a.sizes)),
            "rows": rows,
        },
    )


if __name__ == "__main__":
    main()
