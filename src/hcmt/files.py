"""Files written safely, the ground floor every layer may use: :func:`atomic_path` (write to a temporary file, then
rename: nothing half-written), :func:`check_apart` (no output on an input, or in a folder a command reads),
:func:`undo_on_error` (a failed command leaves none of its new files), :func:`take_lock` (one writer per run folder
or study row), :func:`folder_lock` and :func:`lock_holder` (one ``hcmt generate`` per dataset folder, and whether
one is writing it), :func:`ensure_space` (refuse a write the disk cannot hold, before HDF5 tries) and
:func:`read_json` (a damaged file is one line)."""

from __future__ import annotations

import errno
import fcntl
import json
import os
import shutil
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from hcmt.errors import InputError


def read_json(path: str | os.PathLike, written_by: str):
    """A JSON file's content; one that is not UTF-8 or not JSON (truncated, hand-edited) is one line naming it and
    what writes it (``written_by``, e.g. "`hcmt evaluate`")."""
    try:
        return json.loads(Path(path).read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(
            f"{path}: damaged, not readable JSON ({exc.__class__.__name__}: {str(exc)[:80]}); it is "
            f"written by {written_by}"
        ) from None


@contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success rename it onto ``path``, on failure delete it."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    tmp = Path(tmp)
    try:
        yield tmp
        os.chmod(tmp, 0o644)  # mkstemp creates 0600; a dataset is meant to be shared
        os.replace(tmp, path)
    except OSError as exc:
        named = getattr(exc, "filename", None)
        if exc.errno is None or (named and str(named) != str(tmp)):
            raise
        raise OSError(exc.errno, exc.strerror, str(path)) from None  # the user's path, never the temporary one
    finally:
        if tmp.exists():
            tmp.unlink()


def check_apart(
    outputs: dict[str, str | os.PathLike | None],
    inputs: dict[str, str | os.PathLike | None] | list[tuple[str, str | os.PathLike | None]],
    owned: tuple[str, ...] = (),
) -> None:
    """The one rule of where a command may write: refuse (one line naming both, :class:`InputError`) an output that
    is one of the inputs or lies inside an input folder (a dataset, a run folder the command reads), and an output
    folder named in ``owned`` (one the command fills or may delete) that holds an input. Keys are what the message
    calls each path (a flag, ``DATA``; ``inputs`` may be (name, path) pairs, for names repeated); None values are
    skipped. Paths are compared resolved (relative, ``..``,
    symlinks: :func:`os.path.realpath`) and, where both exist, by file identity (hard links)."""
    for out_name, out in outputs.items():
        if out is None or not str(out).strip():
            continue
        o = Path(os.path.realpath(out))
        for in_name, inp in inputs.items() if isinstance(inputs, dict) else inputs:
            if inp is None or not str(inp).strip():
                continue
            i = Path(os.path.realpath(inp))
            kind = "folder" if i.is_dir() else "file"
            if o == i or (o.exists() and i.exists() and os.path.samefile(o, i)):
                raise InputError(
                    f"{out_name} {out}: the same {kind} as {in_name} {inp}, which this command reads; "
                    "write the output elsewhere"
                )
            if i.is_dir() and o.is_relative_to(i):
                raise InputError(
                    f"{out_name} {out}: inside {in_name} {inp}, a folder this command reads; write the "
                    "output outside it"
                )
            if out_name in owned and i.is_relative_to(o):
                raise InputError(
                    f"{out_name} {out}: holds {in_name} {inp}, which this command reads; choose another folder"
                )


@contextmanager
def undo_on_error(*paths: str | os.PathLike | None) -> Iterator[None]:
    """Around a command's writing: when the block fails, delete what it added under ``paths`` (output files and
    folders; None skipped): a file that did not exist before, and in a folder every file and sub-folder that was not
    there (the folder too when the block created it), so a failed command leaves nothing behind."""
    before: dict[Path, set[Path] | None] = {}
    for p in paths:
        if p is not None:
            p = Path(p)
            before[p] = set(p.rglob("*")) if p.is_dir() else ({p} if p.exists() else None)
    try:
        yield
    except BaseException:
        for p, had in before.items():
            if p.is_dir():
                new = sorted(set(p.rglob("*")) - (had or set()), key=lambda q: len(q.parts), reverse=True)
                for q in new:
                    if q.is_dir() and not q.is_symlink():
                        if not any(q.iterdir()):
                            q.rmdir()
                    else:
                        q.unlink(missing_ok=True)
                if had is None and not any(p.iterdir()):
                    p.rmdir()
            elif had is None and (p.exists() or p.is_symlink()):
                p.unlink(missing_ok=True)
        raise


def take_lock(lock: str | os.PathLike) -> int | None:
    """Create ``lock`` holding this process's pid. Returns None when taken, else the pid of the live process that
    already holds it (possibly this one); a lock whose process is gone is taken over."""
    lock = Path(lock)
    lock.parent.mkdir(parents=True, exist_ok=True)
    for _ in range(2):
        try:
            fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
        except FileExistsError:
            try:
                pid = int(lock.read_text() or 0)
                os.kill(pid, 0)
            except (ProcessLookupError, ValueError):
                lock.unlink(missing_ok=True)  # stale: its process is gone
                continue
            except PermissionError:  # alive, another user's
                pass
            return pid
        with os.fdopen(fd, "w") as f:
            f.write(str(os.getpid()))
        return None
    raise OSError(f"{lock}: cannot take the lock")


def ensure_space(path: str | os.PathLike, nbytes: int, margin: int = 1 << 20) -> None:
    """Refuse (``OSError`` ENOSPC naming ``path``) to write ``nbytes`` where the disk has less free space, before
    HDF5 tries: its library can crash on a full disk instead of raising. Uncompressed sizes, so conservative."""
    folder = Path(path).parent
    free = shutil.disk_usage(folder if folder.exists() else Path.cwd()).free
    if free < nbytes + margin:
        raise OSError(
            errno.ENOSPC,
            f"No space left on device ({free / 1e6:.1f} MB free, about {(nbytes + margin) / 1e6:.1f} MB needed)",
            str(path),
        )


def lock_holder(lock: str | os.PathLike) -> int | None:
    """The pid held in ``lock`` while a process holds it (:func:`folder_lock`), else None (no lock file, or one left
    by a process that has ended: ``flock`` is released with its process). Never creates the file."""
    try:
        fd = os.open(lock, os.O_RDONLY)
    except OSError:
        return None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            text = os.pread(fd, 32, 0).decode(errors="replace").strip()
            return int(text) if text.isdigit() else 0
        fcntl.flock(fd, fcntl.LOCK_UN)
        return None
    finally:
        os.close(fd)


@contextmanager
def folder_lock(lock: str | os.PathLike, busy) -> Iterator[None]:
    """Hold ``lock`` (``fcntl.flock``, exclusive, this process's pid written in it) for the block, then remove it.
    A lock held by a live process raises ``busy(pid)``; one left by a killed process blocks nothing (the kernel
    released it). The file is removed while still held, and a lock taken on a file that was meanwhile removed is
    taken again on the new one, so two processes never both hold it."""
    lock = Path(lock)
    while True:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
        for attempt in range(5):  # a reader's brief look (lock_holder) is waited out
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if attempt == 4:
                    text = os.pread(fd, 32, 0).decode(errors="replace").strip()
                    os.close(fd)
                    raise busy(int(text) if text.isdigit() else 0) from None
                time.sleep(0.02)
        try:
            same = os.path.samestat(os.fstat(fd), os.stat(lock))
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)  # removed by the holder that just ended: take the new file's lock
    try:
        os.ftruncate(fd, 0)
        os.pwrite(fd, str(os.getpid()).encode(), 0)
        yield
    finally:
        lock.unlink(missing_ok=True)
        os.close(fd)
