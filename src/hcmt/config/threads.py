"""Torch's CPU threads: the machine's cores (the bound of ``--threads`` and ``--workers``), ``auto`` (the cores not
busy with other work), a command's ``--threads`` and the Python API's default. Light: torch is imported only inside
the functions that set it, so the command's parsers stay fast."""

from __future__ import annotations

import os
from pathlib import Path


def machine_cores() -> int:
    """The CPU cores this process may run on: the bound of ``--threads`` and ``--workers``."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


#: the torch thread counts hcmt set in this process: ``chosen``, a command's ``--threads`` (:func:`set_threads`);
#: ``auto``, the Python API's default (:func:`default_threads`)
_THREADS: dict[str, int] = {}


def auto_threads() -> int:
    """The CPU cores not already busy: cores minus the 1-minute load average (at least 1). On a machine whose other
    cores run another job this is 1 thread, never the oversubscribed default that made a design take 10x longer
    (docs/RESULTS.md, "Threads")."""
    cores = machine_cores()
    try:
        busy = os.getloadavg()[0]
    except OSError:  # no load average on this platform
        busy = 0.0
    return max(1, min(cores, int(cores - busy + 0.5)))


def set_threads(threads: int | str) -> int:
    """Apply ``--threads`` (1 to the machine's cores, or ``auto``: refused above by its parser) to torch's intra-op
    pool; returns the number set. The API keeps it (:func:`default_threads`)."""
    import torch  # heavy: loaded only by what computes (this module stays light: `hcmt --help` stays fast)

    n = auto_threads() if threads == "auto" else int(threads)
    torch.set_num_threads(n)
    _THREADS["chosen"] = n
    return n


def default_threads() -> int:
    """The Python API's torch threads (``hcmt.train``, ``hcmt.evaluate``, ``hcmt.predict_designs``): the command's
    default, :func:`auto_threads`, applied to torch unless the caller chose a count: ``OMP_NUM_THREADS`` or
    ``MKL_NUM_THREADS`` set, a command's ``--threads`` (:func:`set_threads`), or ``torch.set_num_threads`` called
    with a count other than torch's own start value (:func:`_torch_start_counts`). Chosen once per process, as a
    command chooses at its start (two calls of one script compute alike). Returns the count in use."""
    import torch  # loaded already by the API that calls this

    now = torch.get_num_threads()
    if now in (_THREADS.get("chosen"), _THREADS.get("auto")) or any(
        os.environ.get(v) for v in ("OMP_NUM_THREADS", "MKL_NUM_THREADS")
    ):
        return now  # a command's --threads, this default chosen before, or the environment's
    if now not in _torch_start_counts():
        return now  # the caller's torch.set_num_threads
    n = auto_threads()
    if n != now:
        torch.set_num_threads(n)
    _THREADS["auto"] = n
    return n


def _torch_start_counts() -> set[int]:
    """The thread counts torch may start with here: OpenMP's, the CPUs this process may run on; MKL's and torch's
    own pool's, their physical cores (read on Linux; elsewhere the CPUs only: a count not recognized is kept)."""
    cpus = os.sched_getaffinity(0) if hasattr(os, "sched_getaffinity") else range(os.cpu_count() or 1)
    cores = set()
    for cpu in cpus:
        top = Path(f"/sys/devices/system/cpu/cpu{cpu}/topology")
        try:
            cores.add(((top / "physical_package_id").read_text().strip(), (top / "core_id").read_text().strip()))
        except OSError:
            cores.add(("", str(cpu)))  # no topology: counted as a core of its own
    return {len(cpus), len(cores), os.cpu_count() or 1}
