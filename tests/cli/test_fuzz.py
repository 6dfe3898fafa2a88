"""Fuzz: random byte flips and truncations of a small native split file and of a small TFRecord, given to `info`,
`convert`, `train` and `evaluate`. Every run either succeeds with data equal to the original or exits 2 with one
line on stderr: no traceback, no crash, no hang (each call bounded by an alarm)."""

import shutil
import signal

import numpy as np
import pytest

from conftest import TINY
from hcmt.cli import main as cli
from hcmt.data.format import open_split
from layouts import sphere_simple_tfrecord, write_impact_like

CASES = 14  # per file kind: flips at random offsets, then truncations
# this file's runs: conftest's TINY, then these (narrower, one MGN block, no normalizer warm-up)
EXTRA = ["model.hidden=8", "model.blocks=1", "train.normalizer_steps=0", "train.contact_radius=0.3"]


class Hang(Exception):
    pass


def bounded(argv, capsys, seconds=60):
    """(exit status, stderr lines) of one CLI call; a call running past ``seconds`` fails the test."""

    def alarm(signum, frame):
        raise Hang(f"{argv[0]} hung")

    old = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(seconds)
    try:
        rc = cli(argv)
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
    err = capsys.readouterr().err.strip().splitlines()
    return rc, [l for l in err if not l.startswith("hcmt predict: warning")]


def corruptions(data: bytes, seed: int):
    """(label, corrupted bytes): CASES - 4 flips of 1-4 bytes at random offsets, then 4 truncations."""
    rng = np.random.default_rng(seed)
    for k in range(CASES - 4):
        b = bytearray(data)
        for off in rng.choice(len(b), size=int(rng.integers(1, 5)), replace=False):
            b[off] ^= int(rng.integers(1, 256))
        yield f"flip{k}", bytes(b)
    for frac in (0.1, 0.5, 0.9, 0.999):
        yield f"cut{frac}", data[: int(len(data) * frac)]


def same_split(a, b, split) -> bool:
    with open_split(a, split) as x, open_split(b, split) as y:
        if x.names != y.names:
            return False
        for i in range(len(x)):
            if x.attrs(i) != y.attrs(i):
                return False
            fa, fb = x[i], y[i]
            if any(not np.array_equal(fa[k], fb[k]) for k in fa):
                return False
    return True


def check(rc, err, what):
    assert rc in (0, 2), f"{what}: exit {rc}: {err}"
    assert not any("Traceback" in l for l in err), f"{what}: {err}"
    if rc == 2:
        assert len(err) == 1 and err[0].startswith("hcmt "), f"{what}: {err}"


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    root = tmp_path_factory.mktemp("fuzz")
    data = write_impact_like(root / "data", n_train=1, n_valid=1, n_test=1, steps=4)
    assert (
        cli(
            [
                "train",
                "--config",
                "impact_plate_cpu",
                "--data",
                str(data),
                "--model",
                "mgn",
                "--out",
                str(root / "run"),
                "--no-progress",
                "--steps",
                "1",
            ]
            + [a for t in TINY + EXTRA for a in ("--set", t)]
        )
        == 0
    )
    return root


def test_fuzz_native_split(clean, tmp_path, capsys):
    src = clean / "data"
    original = (src / "test.h5").read_bytes()
    outcomes = {0: 0, 2: 0}
    for label, blob in corruptions(original, seed=0):
        data = tmp_path / label
        shutil.copytree(src, data)
        (data / "test.h5").write_bytes(blob)
        rc, err = bounded(["info", str(data)], capsys)
        check(rc, err, f"info {label}")
        if rc == 0:
            assert same_split(data, src, "test"), f"info {label}: accepted data that differs from the original"
        outcomes[rc] += 1
        # training reads train/valid only: make the corrupted file the training split
        shutil.copy(data / "test.h5", data / "train.h5")
        rc, err = bounded(
            [
                "train",
                "--config",
                "impact_plate_cpu",
                "--data",
                str(data),
                "--model",
                "mgn",
                "--out",
                str(tmp_path / f"run_{label}"),
                "--no-progress",
                "--steps",
                "1",
            ]
            + [a for t in TINY + EXTRA for a in ("--set", t)],
            capsys,
        )
        check(rc, err, f"train {label}")
        run = tmp_path / f"eval_{label}"
        shutil.copytree(clean / "run", run)
        rc, err = bounded(["evaluate", str(run), "--data", str(data), "--split", "test"], capsys)
        check(rc, err, f"evaluate {label}")
        shutil.rmtree(data)
    assert outcomes[2] >= CASES // 2  # most corruptions are caught (checksums), not silently accepted


def test_fuzz_tfrecord(tmp_path, capsys):
    src = tmp_path / "src"
    sphere_simple_tfrecord(src)
    assert cli(["convert", str(src), str(tmp_path / "ref")]) == 0
    original = (src / "test.tfrecord").read_bytes()
    caught = 0
    for label, blob in corruptions(original, seed=1):
        bad = tmp_path / f"src_{label}"
        shutil.copytree(src, bad)
        (bad / "test.tfrecord").write_bytes(blob)
        out = tmp_path / f"out_{label}"
        rc, err = bounded(["convert", str(bad), str(out)], capsys)
        check(rc, err, f"convert {label}")
        if rc == 0:
            assert same_split(out, tmp_path / "ref", "test"), f"convert {label}: different data accepted"
            rc, err = bounded(["info", str(out)], capsys)
            assert rc == 0, err
        else:
            caught += 1
            assert not (out / "test.h5").exists()  # nothing that looks complete
    assert caught >= CASES - 4  # every record byte is covered by a CRC-32C: flips and cuts are all caught
