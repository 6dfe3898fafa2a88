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
            for k, v in params.items():
                lines.append(f"    {k:<14} {min(v):.6g} .. {max(v):.6g}")
    return "\n".join(lines)


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("dataset", help="native dataset folder (meta.json + <split>.h5)")


def main(args: argparse.Namespace) -> int:
    print(summarize(args.dataset))
    return 0
