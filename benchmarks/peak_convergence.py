"""The peak plate stress and deflection of one plate as the mesh refines (docs/solver.md, "Panel families").

    python benchmarks/peak_convergence.py [--sizes 0.3 0.2 0.15]

A 0.9 mm glass plate of the small preset (radius 12 mm, ball 3.75 mm, 750 mm drop, 45 frames): the nodal peak
under the ball at each mesh size beside the deflection. Writes benchmarks/results/peak_convergence.json.
"""
from __future__ import annotations

import argparse

import numpy as np
from common import write_json

from hcmt.sim.scene import Design, Settings, simulate


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizes", nargs="+", type=float, default=[0.3, 0.2, 0.15])
    a = p.parse_args()
    rows = []
    for h in a.sizes:
        r = simulate(Design(thickness=0.9, mesh_size=h, ball_radius=3.75, plate_half_length=12.0), Settings(frames=45))
        f = r["fields"]
        plate = (f["node_type"][:, 0] != 1) & (f["mesh_pos"][:, 1] <= 1e-9)
        x = f["world_pos"]
        rows.append({"mesh_size": h, "nodes": r["info"]["num_nodes"],
                     "peak_plate_stress_mpa": float(f["stress"][:, plate].max()),
                     "max_deflection_mm": float(np.abs(x[:, plate, 1] - x[0, plate, 1]).max())})
        print(rows[-1], flush=True)
    write_json("peak_convergence.json", {"command": "python benchmarks/peak_convergence.py --sizes "
                                         + " ".join(map(str, a.sizes)), "rows": rows})


if __name__ == "__main__":
    main()
