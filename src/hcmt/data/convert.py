"""``hcmt convert SRC OUT``: published datasets into the native format.

SRC is either a MeshGraphNets / HCMT TFRecord folder (``meta.json`` + ``<split>.tfrecord``) or a Deformable Plate
(GGNS) folder of pickles (``<split>.pkl``) or a single pickle, read by a restricted unpickler (numpy arrays and plain
containers only: :func:`hcmt.data.ggns.load_ggns_pickle`; no code a pickle names runs). Every split found is
converted; each output file is written atomically and the output's ``meta.json`` last, so an interrupted or refused
conversion leaves no dataset that looks complete. ``static_varlen`` fields (the official Impact Plate data's
precomputed hierarchy) are not copied: hcmt builds its own hierarchy (``hcmt hierarchy``).
"""

from __future__ import annotations

import shutil
from pathlib import Path

from hcmt.data.format import make_meta, write_meta, write_split
from hcmt.data.ggns import ggns_features, ggns_to_native, load_ggns_pickle
from hcmt.data.tfrecord import iter_tfrecord, read_tf_meta
from hcmt.errors import DatasetError, InputError

_PICKLE_SUFFIXES = (".pkl", ".pickle", ".pk")


def convert_tfrecord(src: Path, out: Path) -> dict:
    tf_meta = read_tf_meta(src)
    splits = sorted(p.stem for p in src.glob("*.tfrecord"))
    if not splits:
        raise DatasetError("no <split>.tfrecord files beside meta.json", file=src)
    features = {}
    for name, spec in tf_meta["features"].items():
        if spec["type"] == "static":
            features[name] = {"type": "static", "shape": spec["shape"][1:], "dtype": spec["dtype"]}
        elif spec["type"] == "dynamic":
            features[name] = dict(spec)
    world = features.get("world_pos") or features.get("mesh_pos")
    length = tf_meta.get("trajectory_length") or next(
        (v["shape"][0] for v in features.values() if v["type"] == "dynamic" and v["shape"][0] > 0), None
    )
    if not length:
        raise DatasetError(
            'has no trajectory_length and no dynamic field with a fixed time axis; add "trajectory_length": T',
            file=src / "meta.json",
        )
    extra = {k: tf_meta[k] for k in ("collision_radius", "simulator") if k in tf_meta}
    meta = make_meta(
        features,
        trajectory_length=length,
        dimension=int(world["shape"][-1]) if world else 0,
        dt=tf_meta.get("dt"),
        units=tf_meta.get("units", {}),
        generator={
            "converted_from": str(src),
            "source_format": "tfrecord",
            "skipped_fields": [k for k, v in tf_meta["features"].items() if v["type"] == "static_varlen"],
        },
        **extra,
    )
    for split in splits:
        if (src / f"{split}.tfrecord").stat().st_size == 0:
            raise DatasetError("is empty: no trajectories to convert", file=src / f"{split}.tfrecord")
        count = [0]

        def trajectories(split=split):
            for i, traj in enumerate(iter_tfrecord(src, split, tf_meta)):
                count[0] += 1
                yield f"traj_{i:05d}", {k: v for k, v in traj.items() if k in features}, {}

        write_split(out / f"{split}.h5", meta, trajectories())
        if not count[0]:
            raise DatasetError("holds no trajectories (no tf.train.Example records)", file=src / f"{split}.tfrecord")
    write_meta(out, meta)
    return meta


def convert_ggns(src: Path, out: Path) -> dict:
    files = [src] if src.is_file() else sorted(p for p in src.iterdir() if p.suffix in _PICKLE_SUFFIXES)
    if not files:
        if src.is_dir() and any(src.glob("*.tfrecord")):
            raise DatasetError(
                "holds .tfrecord files but no meta.json beside them: a TFRecord dataset needs the "
                "meta.json of its download (MeshGraphNets / HCMT)",
                file=src,
            )
        raise DatasetError("no pickle files (*.pkl) and no TFRecord dataset (meta.json + *.tfrecord) found", file=src)
    meta = None
    for path in files:
        trajs = load_ggns_pickle(path)  # a pickle is read whole; its trajectories are converted one at a time
        if not trajs:
            raise DatasetError("holds no trajectories", file=path)
        steps = ggns_to_native(trajs[0], file=path, trajectory=0)[0]["world_pos"].shape[0]
        if meta is not None and steps != meta["trajectory_length"]:
            raise DatasetError(
                f"trajectories have different lengths {sorted({steps, meta['trajectory_length']})}", file=path
            )
        if meta is None:
            meta = make_meta(
                ggns_features(steps),
                trajectory_length=steps,
                dimension=2,
                dt=None,
                units={},
                generator={"converted_from": str(src), "source_format": "ggns-pickle"},
            )
        write_split(out / f"{path.stem}.h5", meta, _ggns_trajectories(trajs, steps, path))
    write_meta(out, meta)
    return meta


def _ggns_trajectories(trajs: list[dict], steps: int, path: Path):
    """``(name, fields, attrs)`` of a pickle's trajectories, converted one at a time (each source dict dropped once
    converted), all of ``steps`` frames."""
    for i in range(len(trajs)):
        fields, attrs = ggns_to_native(trajs[i], file=path, trajectory=i)
        trajs[i] = None
        if fields["world_pos"].shape[0] != steps:
            raise DatasetError(
                f"trajectories have different lengths {sorted({steps, fields['world_pos'].shape[0]})}", file=path
            )
        yield f"traj_{i:05d}", fields, attrs


def convert(src: str | Path, out: str | Path) -> dict:
    """Convert SRC into a native dataset at OUT; on any error nothing new is left at OUT."""
    src, out = Path(src), Path(out)
    if not src.exists():
        raise InputError(
            f"{src}: no such file or folder; expected a TFRecord dataset folder or GGNS pickle(s)", param="src"
        )
    if (out / "meta.json").exists():
        raise DatasetError("already holds a dataset; choose another output folder or delete it", file=out)
    existed = out.exists()
    out.mkdir(parents=True, exist_ok=True)
    try:
        if src.is_dir() and (src / "meta.json").is_file():
            return convert_tfrecord(src, out)
        if src.suffix in _PICKLE_SUFFIXES or src.is_dir():
            return convert_ggns(src, out)
        raise DatasetError("not a TFRecord dataset folder (meta.json + *.tfrecord) nor a GGNS pickle", file=src)
    except BaseException:
        for p in out.glob("*.h5"):
            p.unlink()
        if not existed:
            shutil.rmtree(out, ignore_errors=True)
        raise
