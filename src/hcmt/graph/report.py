"""``hcmt hierarchy DATASET --levels L [--json FILE]``: build a dataset's mesh hierarchies and report, per level,
node and edge counts and cell quality before and after remeshing (paper appendix, Tables 6 and 7).

* **after** remeshing: the level's Delaunay cells (:func:`hcmt.graph.hierarchy.build_hierarchy`);
* **before** remeshing: the same kept nodes joined as they are without remeshing (BSMS: two hops apart in the
  finer level), measured on that graph's triangles (3-cliques; 4-cliques for tetrahedral meshes). Both columns
  describe the same node set, so the difference is the remeshing alone. Level 0 is the mesh itself (before =
  after).

Values are averaged over the trajectories of the split (the paper: "average values across all levels within the
training data"): each trajectory's per-level means, then their mean. ``edges`` counts undirected edges (the
model's graph holds each twice). Hierarchies are cached in ``DATASET/.cache/hierarchy``.
"""

from __future__ import annotations

import math

import numpy as np
from tqdm import tqdm

from hcmt.data.format import open_split
from hcmt.errors import DatasetError, InputError
from hcmt.graph.hierarchy import Hierarchy, cached_hierarchy, hierarchy_cache_dir
from hcmt.graph.quality import quality_summary
from hcmt.graph.remesh import clique_cells, two_hop_edges

KEYS = (
    "level",
    "nodes",
    "edges",
    "jacobian_before",
    "jacobian_after",
    "min_angle_before",
    "min_angle_after",
    "max_angle_before",
    "max_angle_after",
)


def level_quality(hierarchy: Hierarchy, mesh_pos: np.ndarray) -> list[dict]:
    """Rows (keys :data:`KEYS`) of one mesh's hierarchy; NaN where a level has no cells to measure."""
    mesh_pos = np.asarray(mesh_pos, np.float64)
    k = hierarchy.cells[0].shape[1]
    rows = []
    for level in range(hierarchy.levels + 1):  # one row per level
        pos = mesh_pos[hierarchy.nodes[level]]
        after = quality_summary(pos, hierarchy.cells[level])
        if level == 0:
            before = after
        else:
            n_fine = hierarchy.num_nodes(level - 1)
            hop = two_hop_edges(hierarchy.edges[level - 1], n_fine, hierarchy.pool[level - 1])
            before = quality_summary(pos, clique_cells(hop, hierarchy.num_nodes(level), k))
        rows.append(
            dict(
                level=level,
                nodes=hierarchy.num_nodes(level),
                edges=hierarchy.edges[level].shape[1] // 2,
                jacobian_before=before["jacobian"],
                jacobian_after=after["jacobian"],
                min_angle_before=before["min_angle"],
                min_angle_after=after["min_angle"],
                max_angle_before=before["max_angle"],
                max_angle_after=after["max_angle"],
            )
        )
    return rows


def average_rows(per_trajectory: list[list[dict]]) -> list[dict]:
    """Mean of every key over trajectories (NaN entries ignored); integral means stay integers."""
    out = []
    for level in range(len(per_trajectory[0])):
        row = {"level": level}
        for key in KEYS[1:]:
            vals = np.array([rows[level][key] for rows in per_trajectory], np.float64)
            vals = vals[np.isfinite(vals)]
            mean = float(vals.mean()) if len(vals) else float("nan")
            row[key] = int(mean) if key in ("nodes", "edges") and mean == int(mean) else mean
        out.append(row)
    return out


def format_table(rows: list[dict]) -> str:
    def f(v, spec):
        if isinstance(v, float) and math.isnan(v):
            return "   -  "
        return format(v, "8.1f" if spec == "8g" and isinstance(v, float) else spec)

    lines = [
        f"{'level':>5} {'nodes':>8} {'edges':>8} | {'jacobian':>15} | {'min angle':>15} | {'max angle':>15}",
        f"{'':>5} {'':>8} {'':>8} | {'before  after':>15} | {'before  after':>15} | {'before  after':>15}",
    ]
    for r in rows:
        lines.append(
            f"{r['level']:>5} {f(r['nodes'], '8g')} {f(r['edges'], '8g')} | "
            f"{f(r['jacobian_before'], '6.3f')}  {f(r['jacobian_after'], '6.3f')} | "
            f"{f(r['min_angle_before'], '6.1f')}  {f(r['min_angle_after'], '6.1f')} | "
            f"{f(r['max_angle_before'], '6.1f')}  {f(r['max_angle_after'], '6.1f')}"
        )
    if len(rows) > 1:  # the paper's Table 7 averages the pooled levels
        mean = {k: float(np.nanmean([r[k] for r in rows[1:]])) for k in KEYS[3:]}
        lines.append(
            f"{'1..' + str(rows[-1]['level']):>5} {'':>8} {'':>8} | "
            f"{mean['jacobian_before']:6.3f}  {mean['jacobian_after']:6.3f} | "
            f"{mean['min_angle_before']:6.1f}  {mean['min_angle_after']:6.1f} | "
            f"{mean['max_angle_before']:6.1f}  {mean['max_angle_after']:6.1f}"
        )
    return "\n".join(lines)


def dataset_quality(
    dataset, split: str, levels: int, *, trajectories: int = 0, cache: bool = True
) -> tuple[int, list[dict]]:
    """(trajectories read, per-level rows averaged over them: :func:`level_quality`, :func:`average_rows`) of the
    first ``trajectories`` of a split (0: all); hierarchies cached in ``DATASET/.cache/hierarchy`` with ``cache``."""
    if levels < 0:
        raise InputError(f"must be >= 0, got {levels}", param="levels")
    if trajectories < 0:
        raise InputError(f"must be >= 0 (0: all), got {trajectories}", param="trajectories")
    reader = open_split(dataset, split)
    count = len(reader) if trajectories <= 0 else min(trajectories, len(reader))
    if count == 0:
        raise InputError(f"split {split!r} of {dataset} has no trajectories")
    cache_dir = hierarchy_cache_dir(dataset) if cache else None
    per_trajectory = []
    for i in tqdm(range(count), desc="hierarchy", unit="traj", disable=count < 20):  # one mesh per trajectory
        traj = reader[i]
        try:
            h = cached_hierarchy(
                traj["mesh_pos"], traj["cells"], traj["node_type"].reshape(-1), levels, remesh=True, cache_dir=cache_dir
            )
        except ValueError as exc:  # DatasetError included: say which trajectory
            raise DatasetError(str(exc), file=reader.path, trajectory=reader.names[i]) from None
        per_trajectory.append(level_quality(h, traj["mesh_pos"]))
    return count, average_rows(per_trajectory)
