"""The propagation argument with numbers: how far (in mesh hops) the impact's stress travels per recorded frame, and
how far each model can carry information in one step, on generated Impact Plate data of both presets.

    python benchmarks/parity/propagation.py --data small=PATH --data paper=PATH [--split test] [--levels-small 4]
                                     [--levels-paper 6] [--L-C 2] [--blocks-small 11] [--blocks-paper 15]

Per trajectory (plate only; hops counted on the plate's mesh edges from the plate node under the ball's first
contact, x = 0 on the top surface):

* ``impact_to_clamp_hops``: hops from the impact node to the nearest clamped (HANDLE) node;
* ``front_hops_per_frame``: the stress front is the farthest plate node (in hops) whose von Mises stress exceeds
  0.5 % of the trajectory's peak; its advance per frame, median over the frames while it grows and has not reached
  the clamp;
* ``p_wave_hops_per_frame``: the plate's P-wave speed sqrt(E(1-ν)/(ρ(1+ν)(1-2ν))) times the frame time, divided by
  the median plate edge length.

Per model (same graph): MGN and GT move information one hop per block (``blocks``); HCMT ``L_C`` hops in CMT plus,
through the hierarchy, each HMT block's median span in level-0 hops (a level-``l`` edge joins nodes that are
``span_l`` plate hops apart; the U has one block per level on the way down and up and one at the bottom).
Writes benchmarks/results/propagation.json.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import scipy.sparse as sp
import scipy.sparse.csgraph as csgraph

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # benchmarks/: common
from common import write_json  # noqa: E402
from hcmt.data.format import NodeType, Split  # noqa: E402
from hcmt.graph.hierarchy import build_hierarchy  # noqa: E402
from hcmt.inference.metrics import plate_mask  # noqa: E402


def hop_matrix(edges: np.ndarray, n: int, sources: np.ndarray) -> np.ndarray:
    adj = sp.coo_matrix((np.ones(edges.shape[1]), (edges[0], edges[1])), shape=(n, n)).tocsr()
    return csgraph.shortest_path(adj, unweighted=True, indices=sources)


def trajectory_numbers(tr: dict, attrs: dict, frame_dt: float) -> dict:
    cells, nt = np.asarray(tr["cells"]), np.asarray(tr["node_type"]).reshape(-1)
    pos0 = np.asarray(tr["mesh_pos"], np.float64)
    plate = plate_mask(cells, nt)
    plate_cells = cells[plate[cells].all(1)]
    e = np.concatenate([plate_cells[:, [0, 1]], plate_cells[:, [1, 2]], plate_cells[:, [2, 0]]]).T
    e = np.concatenate([e, e[::-1]], 1)
    top = np.flatnonzero(plate & (np.abs(pos0[:, 0]) < 1e-9))
    impact = top[np.argmax(pos0[top, 1])]
    hops = hop_matrix(e, len(nt), np.array([impact]))[0]
    clamp = float(hops[nt == NodeType.HANDLE].min())
    s = np.asarray(tr["stress"])[..., 0][:, plate]
    hp = hops[plate]
    threshold = 0.005 * s.max()
    front = np.array([hp[s[t] > threshold].max() if (s[t] > threshold).any() else 0.0 for t in range(len(s))])
    grow = np.diff(front)
    growing = grow[(grow > 0) & (front[1:] < clamp)]
    lengths = np.linalg.norm(pos0[e[0]] - pos0[e[1]], axis=1)
    E, nu, rho = attrs["plate_modulus"], attrs["plate_poisson"], attrs["plate_density"]
    c = np.sqrt(E * (1 - nu) / (rho * (1 + nu) * (1 - 2 * nu)))  # MPa / (g/mm^3) -> mm^2/ms^2
    return {
        "impact_to_clamp_hops": clamp,
        "front_hops_per_frame": float(np.median(growing)) if len(growing) else 0.0,
        "frames_to_reach_clamp": int(np.argmax(front >= clamp)) if (front >= clamp).any() else None,
        "p_wave_hops_per_frame": float(c * frame_dt / np.median(lengths)),
        "median_edge_mm": float(np.median(lengths)),
    }


def hcmt_reach(tr: dict, levels: int, L_C: int) -> dict:
    """Median level-0 hop span of each level's edges, and HCMT's hops per step L_C + 2 Σ_{l<λ} span_l + span_λ."""
    cells, nt = np.asarray(tr["cells"]), np.asarray(tr["node_type"]).reshape(-1)
    h = build_hierarchy(np.asarray(tr["mesh_pos"]), cells, nt, levels=levels)
    n = h.num_nodes(0)
    spans = []
    for l in range(levels + 1):
        nodes, e = h.nodes[l], h.edges[l]
        senders = np.unique(e[0])
        d = hop_matrix(h.edges[0], n, nodes[senders])
        row = np.searchsorted(senders, e[0])
        span = d[row, nodes[e[1]]]
        spans.append(float(np.median(span[np.isfinite(span)])))
    return {"span_per_level": spans, "hops_per_step": L_C + 2 * sum(spans[:levels]) + spans[levels]}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", action="append", required=True, metavar="PRESET=PATH")
    p.add_argument("--split", default="test")
    p.add_argument("--limit", type=int, default=4, help="trajectories per preset")
    p.add_argument("--levels-small", type=int, default=4)
    p.add_argument("--levels-paper", type=int, default=6)
    p.add_argument("--L-C", type=int, default=2)
    p.add_argument("--blocks-small", type=int, default=11)
    p.add_argument("--blocks-paper", type=int, default=15)
    a = p.parse_args()
    out = {}
    for item in a.data:
        preset, _, path = item.partition("=")
        levels, blocks = (a.levels_small, a.blocks_small) if preset == "small" else (a.levels_paper, a.blocks_paper)
        with Split(path, a.split) as s:
            frame_dt = float(s.meta["dt"])
            rows = [trajectory_numbers(s[i], s.attrs(i), frame_dt) for i in range(min(a.limit, len(s)))]
            reach = hcmt_reach(s[0], levels, a.L_C)
        summary = {k: float(np.median([r[k] for r in rows if r[k] is not None])) for k in rows[0]}
        out[preset] = {
            "data": path,
            "trajectories": len(rows),
            "per_trajectory": rows,
            "median": summary,
            "models": {"mgn_gt_hops_per_step": blocks, "hcmt": {"levels": levels, "L_C": a.L_C, **reach}},
        }
        m = summary
        print(
            f"{preset}: impact->clamp {m['impact_to_clamp_hops']:.0f} hops; stress front "
            f"{m['front_hops_per_frame']:.1f} hops/frame (P wave {m['p_wave_hops_per_frame']:.1f}); "
            f"MGN/GT {blocks} hops/step; HCMT {reach['hops_per_step']:.0f} hops/step "
            f"(level spans {', '.join(f'{x:.0f}' for x in reach['span_per_level'])})"
        )
    print(f"wrote {write_json('propagation.json', out)}")


if __name__ == "__main__":
    main()
