"""``hcmt info DATASET``: what a native dataset holds."""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from hcmt.data.format import NodeType, Split, list_splits, read_meta


def summarize(dataset_dir: str | Path) -> str:
    """Splits, trajectory counts, nodes min/mean/max, steps, fields, node-type counts, design-parameter ranges."""
    meta = read_meta(dataset_dir)
    lines = [f"dataset {dataset_dir}", f"  dimension {meta.get('dimension')}, steps {meta['trajectory_length']}, "
             f"dt {meta.get('dt')} {meta.get('units', {}).get('time', '')}".rstrip()]
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
            nodes = np.array([s.num_nodes(i) for i in range(len(s))])
            types = np.zeros(len(NodeType), dtype=np.int64)
            params: dict[str, list] = {}
            for i in range(len(s)):
                nt = s._file[s.names[i]]["node_type"][()].reshape(-1)
                types += np.bincount(nt, minlength=len(NodeType))[: len(NodeType)]
                for k, v in s.attrs(i).items():
                    if isinstance(v, (int, float, np.number)):
                        params.setdefault(k, []).append(float(v))
            lines.append(f"  split {split}: {len(s)} trajectories, nodes min/mean/max "
                         f"{nodes.min()}/{nodes.mean():.1f}/{nodes.max()}")
            lines.append("    node types (total over trajectories): "
                         + ", ".join(f"{t.name} {types[t]}" for t in NodeType if types[t]))
            lines += displacement_lines(s, meta)
            for k, v in params.items():
                lines.append(f"    {k:<14} {min(v):.6g} .. {max(v):.6g}")
    return "\n".join(lines)


def position_fields(meta: dict) -> list[str]:
    """Dynamic fields holding positions: ``*_pos`` with the dataset's dimension as last axis (e.g. ``world_pos``)."""
    d = meta.get("dimension")
    return [n for n in meta["field_names"] if meta["features"][n]["type"] == "dynamic" and n.endswith("pos")
            and (d is None or meta["features"][n]["shape"][-1] == d)]


def displacement_stats(split: Split, field: str) -> dict[str, dict[str, float]]:
    """Per node type: median, 90th percentile and max of the per-frame displacement ``|x^{t+1} - x^t|`` of a
    position field over every node and frame of the split (to choose the training noise σ against)."""
    per_type: dict[str, list[np.ndarray]] = {}
    for i in range(len(split)):
        group = split._file[split.names[i]]
        x = np.asarray(group[field][()], np.float64)
        nt = group["node_type"][()].reshape(-1)
        step = np.linalg.norm(np.diff(x, axis=0), axis=-1)  # [T-1, N]
        for t in np.unique(nt):
            name = NodeType(int(t)).name if int(t) in NodeType._value2member_map_ else str(int(t))
            per_type.setdefault(name, []).append(step[:, nt == t].ravel())
    out = {}
    for name, parts in per_type.items():
        v = np.concatenate(parts)
        out[name] = {"median": float(np.median(v)), "p90": float(np.percentile(v, 90)), "max": float(v.max())}
    return out


def displacement_lines(split: Split, meta: dict) -> list[str]:
    unit = meta.get("units", {}).get("length", "")
    lines = []
    for field in position_fields(meta):
        lines.append(f"    per-frame displacement |{field}^(t+1) - {field}^t| {unit} (median / 90th pct / max):")
        for name, st in displacement_stats(split, field).items():
            lines.append(f"      {name:<10} {st['median']:.3g} / {st['p90']:.3g} / {st['max']:.3g}")
    return lines


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("dataset", help="native dataset folder (meta.json + <split>.h5)")


def main(args: argparse.Namespace) -> int:
    print(summarize(args.dataset))
    return 0
