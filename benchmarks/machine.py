"""The benchmark machine's fixed facts, read once for every script that reports a share of the hardware's limit (no
torch, no hcmt: the peers' orchestrator imports it too)."""

from __future__ import annotations

import platform
import re
from pathlib import Path


def core_peak() -> dict:
    r"""The core's fp32 peak, :math:`\text{FMA units} \times \text{lanes} \times 2 \times f`: lanes from the widest
    vector flag in /proc/cpuinfo (avx512f: 16, avx2: 8, else 4), two FMA units (an assumption: Intel server cores
    since Skylake-SP have two 512-bit FMA ports; the hypervisor hides the exact part), ``f`` the ``cpu MHz`` the
    kernel reports (nominal; turbo would raise the peak, so the share is an upper bound)."""
    text = Path("/proc/cpuinfo").read_text() if Path("/proc/cpuinfo").is_file() else ""
    flags = set(re.search(r"^flags\s*:(.*)$", text, re.M).group(1).split()) if "flags" in text else set()
    lanes = 16 if "avx512f" in flags else 8 if "avx2" in flags else 4
    mhz = re.search(r"^cpu MHz\s*:\s*([\d.]+)", text, re.M)
    ghz = float(mhz.group(1)) / 1000 if mhz else float("nan")
    model = re.search(r"^model name\s*:\s*(.*)$", text, re.M)
    return {
        "cpu": model.group(1) if model else platform.processor(),
        "ghz": ghz,
        "fp32_lanes": lanes,
        "fma_units": 2,
        "gflops": 2 * lanes * 2 * ghz,
        "derivation": f"2 FMA units x {lanes} fp32 lanes x 2 FLOP/FMA x {ghz:.2f} GHz (cpu MHz of /proc/cpuinfo)",
    }
