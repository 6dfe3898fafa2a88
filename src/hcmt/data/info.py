"""``hcmt info DATASET``: what a native dataset holds."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from hcmt.data.format import NodeType, Split, incomplete, list_splits, read_meta
from hcmt.errors import DatasetError


def summarize(dataset_dir: str | Path, all_params: bool = False) -> str:
    """Splits, trajectory counts, nodes min/mean/max, steps, fields, node-type counts, design-parameter ranges
    (the parameters that vary over a split, one line each; the constant ones in one line, or each on its own line
    with ``all_params``: :func:`param_lines`) and the per-frame displacement per node type. Every trajectory is
    read and validated as training reads it (:class:`hcmt.data.format.Split`): a bad one stops with a
    :class:`DatasetError` naming file, trajectory, field."""
    meta = read_meta(dataset_dir)
    if not list_splits(dataset_dir):
        raise DatasetError(incomplete(dataset_dir), file=dataset_dir)
    dt = meta.get("dt")
    time_unit = meta.get("units", {}).get("time", "")
    lines = [
        f"dataset {dataset_dir}",
        f"  dimension {meta.get('dimension')}, steps {meta['trajectory_length']}, "
        + (f"dt {dt} {time_unit}".rstrip() if dt is not None else "dt not recorded"),
    ]
    if meta.get("units"):
        lines.append("  units " + ", ".join(f"{k}={v}" for k, v in meta["units"].items()))
    lines.append("  fields:")
    for name in meta["field_names"]:
        spec = meta["features"][name]
        lines.append(f"    {name:<14} {spec['type']:<8} {spec['dtype']:<8} {spec['shape']}")
    for split in list_splits(dataset_dir):
        with Split(dataset_dir, split, meta) as s:
            if len(s) == 0:
                lines.append(f"  split {split}: 0 trajectories")
                continue
            nodes, types, params, families = [], np.zeros(len(NodeType), dtype=np.int64), {}, {}
            steps: dict[str, dict[str, list[np.ndarray]]] = {}
            for i in range(len(s)):
                f = s[i]  # validated: shapes, dtypes, finite values, cell indices, node types
                nt = f["node_type"].reshape(-1)
                nodes.append(len(nt))
                types += np.bincount(nt, minlength=len(NodeType))[: len(NodeType)]
                for k, v in s.attrs(i).items():
                    if isinstance(v, (int, float, np.number)):
                        params.setdefault(k, []).append(float(v))
                    elif k == "family":  # the design family of a generated panel (hcmt.sim.params.FAMILIES)
                        families[str(v)] = families.get(str(v), 0) + 1
                for field in position_fields(meta):
                    d = np.linalg.norm(np.diff(np.asarray(f[field], np.float64), axis=0), axis=-1)  # [T-1, N]
                    for t in np.unique(nt):
                        steps.setdefault(field, {}).setdefault(NodeType(int(t)).name, []).append(d[:, nt == t].ravel())
            nodes = np.array(nodes)
            lines.append(
                f"  split {split}: {len(s)} trajectories, nodes min/mean/max "
                f"{nodes.min()}/{nodes.mean():.1f}/{nodes.max()}"
            )
            lines.append(
                "    node types (total over trajectories): "
                + ", ".join(f"{t.name} {types[t]}" for t in NodeType if types[t])
            )
            if families:
                lines.append("    families: " + ", ".join(f"{k} {n}" for k, n in sorted(families.items())))
            lines += param_lines(params, all_params)
            lines += displacement_lines(steps, meta.get("units", {}).get("length", ""))
    return "\n".join(lines)


def param_lines(params: dict[str, list[float]], all_params: bool = False) -> list[str]:
    """One line per design parameter that varies over the split (``min .. max``); those that do not, in one line
    ``constant: k=v, ...`` (each on its own line with ``all_params``)."""
    varying = {k: v for k, v in params.items() if min(v) != max(v)}
    constant = {k: v[0] for k, v in params.items() if k not in varying}
    lines = [f"    {k:<14} {min(v):.6g} .. {max(v):.6g}" for k, v in (params if all_params else varying).items()]
    if constant and not all_params:
        lines.append(f"    constant ({len(constant)}): " + ", ".join(f"{k}={v:.6g}" for k, v in constant.items()))
    return lines


def position_fields(meta: dict) -> list[str]:
    """Dynamic fields holding positions: ``*_pos`` with the dataset's dimension as last axis (e.g. ``world_pos``)."""
    d = meta.get("dimension")
    return [
        n
        for n in meta["field_names"]
        if meta["features"][n]["type"] == "dynamic"
        and n.endswith("pos")
        and (d is None or meta["features"][n]["shape"][-1] == d)
    ]


def displacement_lines(steps: dict[str, dict[str, list[np.ndarray]]], unit: str) -> list[str]:
    """Median, 90th percentile and max of the per-frame displacement ``|x^{t+1} - x^t|`` of each position field,
    per node type, over every node and frame of a split: what the training noise σ should be compared with."""
    lines = []
    for field, per_type in steps.items():
        lines.append(
            f"    per-frame displacement |{field}(t+1) - {field}(t)| [{unit or 'length unit'}], "
            "median / 90th percentile / max:"
        )
        for name, parts in per_type.items():
            v = np.concatenate(parts)
            lines.append(f"      {name:<10} {np.median(v):.3g} / {np.percentile(v, 90):.3g} / {v.max():.3g}")
    return lines
