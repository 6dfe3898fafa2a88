"""Read the MeshGraphNets / HCMT TFRecord datasets without TensorFlow.

A dataset is ``meta.json`` + ``<split>.tfrecord``. Each record is a ``tf.train.Example`` whose features are raw
bytes (``np.ndarray.tobytes``) of the dtype named in meta.json. The schema is always taken from meta.json:

* ``static``: stored once with a leading 1 (e.g. ``mesh_pos`` [1,-1,3]); returned without that axis;
* ``dynamic``: stored with the time axis (e.g. ``world_pos`` [400,-1,3]);
* ``static_varlen``: a flat array cut into rows by the int32 row splits in the feature ``length_<name>``
  (the official HCMT Impact Plate data stores its precomputed hierarchy this way); returned as a list of arrays.

The record framing (length, masked CRC-32C of the length, payload, masked CRC-32C of the payload) is read here
rather than by the ``tfrecord`` package so that truncation and checksum errors name the file and record; the
protobuf message itself is parsed with ``tfrecord.example_pb2``. Both packages (``tfrecord``, ``crc32c``) come with
the ``tfrecord`` extra (``pip install 'hcmt[tfrecord]'``) and are imported on first use.
"""

from __future__ import annotations

import json
import os
import struct
from pathlib import Path
from typing import Iterator

import numpy as np

from hcmt.errors import DatasetError, require

_MASK_DELTA = 0xA282EAD8


def _masked_crc(data: bytes) -> int:
    crc = require("crc32c", "tfrecord").crc32c(data)
    return (((crc >> 15) | (crc << 17)) + _MASK_DELTA) & 0xFFFFFFFF


def read_tf_meta(dataset_dir: str | os.PathLike) -> dict:
    path = Path(dataset_dir) / "meta.json"
    if not path.is_file():
        raise DatasetError("not found; a TFRecord dataset is a folder with meta.json and <split>.tfrecord", file=path)
    try:
        meta = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise DatasetError(f"is not valid JSON ({exc.__class__.__name__}: {str(exc)[:80]})", file=path) from None
    for key in ("features", "field_names"):
        if key not in meta:
            raise DatasetError(f"missing key {key!r} expected in a MeshGraphNets meta.json", file=path)
    for name, spec in meta["features"].items():
        if spec.get("type") not in ("static", "dynamic", "static_varlen"):
            raise DatasetError(
                f"type {spec.get('type')!r}; expected static, dynamic or static_varlen", file=path, field=name
            )
    return meta


def iter_records(path: str | os.PathLike) -> Iterator[bytes]:
    """Yield the payload of each record, checking lengths and checksums."""
    path = Path(path)
    size = path.stat().st_size
    with open(path, "rb") as f:
        index = 0
        while f.tell() < size:
            header = f.read(12)
            if len(header) < 12:
                raise DatasetError(
                    f"truncated: record {index} header has {len(header)} of 12 bytes", file=path, trajectory=index
                )
            length_bytes, length_crc = header[:8], struct.unpack("<I", header[8:])[0]
            if _masked_crc(length_bytes) != length_crc:
                raise DatasetError("corrupt record length (checksum mismatch)", file=path, trajectory=index)
            (length,) = struct.unpack("<Q", length_bytes)
            payload = f.read(length)
            footer = f.read(4)
            if len(payload) < length or len(footer) < 4:
                raise DatasetError(
                    f"truncated: record {index} should hold {length} bytes, the file ends first",
                    file=path,
                    trajectory=index,
                )
            if _masked_crc(payload) != struct.unpack("<I", footer)[0]:
                raise DatasetError("corrupt record payload (checksum mismatch)", file=path, trajectory=index)
            yield payload
            index += 1


def _decode(raw: bytes, dtype: str, shape, *, file, trajectory, field) -> np.ndarray:
    dt = np.dtype(dtype)
    if len(raw) % dt.itemsize:
        raise DatasetError(
            f"{len(raw)} bytes is not a whole number of {dtype} values", file=file, trajectory=trajectory, field=field
        )
    flat = np.frombuffer(raw, dtype=dt)
    try:
        return flat.reshape(shape)
    except ValueError:
        raise DatasetError(
            f"{flat.size} {dtype} values cannot take meta.json shape {list(shape)}",
            file=file,
            trajectory=trajectory,
            field=field,
        ) from None


def parse_example(payload: bytes, meta: dict, *, file=None, trajectory=None) -> dict:
    """Decode one record into numpy arrays following meta.json (see module docstring)."""
    example = require("tfrecord.example_pb2", "tfrecord").Example()
    try:
        example.ParseFromString(payload)
    except Exception as exc:  # protobuf raises its own DecodeError type
        raise DatasetError(f"not a tf.train.Example ({exc})", file=file, trajectory=trajectory) from None
    feats = example.features.feature
    out = {}
    for name, spec in meta["features"].items():
        if name not in feats:
            raise DatasetError(
                f"missing from the record; meta.json declares {list(meta['features'])}",
                file=file,
                trajectory=trajectory,
                field=name,
            )
        raw = b"".join(feats[name].bytes_list.value)
        kind = spec["type"]
        if kind == "static_varlen":
            splits_name = f"length_{name}"
            if splits_name not in feats:
                raise DatasetError(
                    f"static_varlen field needs its row splits in feature {splits_name!r}",
                    file=file,
                    trajectory=trajectory,
                    field=name,
                )
            flat = _decode(raw, spec["dtype"], [-1], file=file, trajectory=trajectory, field=name)
            splits = np.frombuffer(b"".join(feats[splits_name].bytes_list.value), dtype=np.int32)
            if splits.size == 0 or splits[0] != 0 or splits[-1] != flat.size or np.any(np.diff(splits) < 0):
                raise DatasetError(
                    f"row splits {splits.tolist()[:8]}... do not partition {flat.size} values",
                    file=file,
                    trajectory=trajectory,
                    field=splits_name,
                )
            out[name] = [flat[a:b] for a, b in zip(splits[:-1], splits[1:])]
            continue
        value = _decode(raw, spec["dtype"], spec["shape"], file=file, trajectory=trajectory, field=name)
        if kind == "static":
            if value.shape[0] != 1:
                raise DatasetError(
                    f"static field should have a leading axis of 1, has shape {list(value.shape)}",
                    file=file,
                    trajectory=trajectory,
                    field=name,
                )
            value = value[0]
        out[name] = value
    return out


def iter_tfrecord(dataset_dir: str | os.PathLike, split: str, meta: dict | None = None) -> Iterator[dict]:
    """Yield each trajectory of ``<dataset_dir>/<split>.tfrecord`` as a dict of numpy arrays."""
    meta = meta or read_tf_meta(dataset_dir)
    path = Path(dataset_dir) / f"{split}.tfrecord"
    if not path.is_file():
        raise DatasetError(f"split {split!r} not found", file=path)
    for index, payload in enumerate(iter_records(path)):
        yield parse_example(payload, meta, file=path, trajectory=index)
