"""What a benchmark says about the machine it ran on, and the reference a budget is stated against.

The machine changes from session to session (a Xeon with AMX, an EPYC with AVX-512, one with AVX2
only), so a speed bar is a ratio to a reference timed in the same run: the median time of one
float32 matrix product of about a billion multiply-adds (two 1024 x 1024 matrices, torch's
default threads), which tracks what the machine's cores and vector units give a dense decoder.
"""

from __future__ import annotations

import os
import time

VECTOR_FLAGS = ("avx2", "fma", "avx512f", "amx_tile")
REFERENCE_SIZE = 1024  # 1024^3 = 1.07e9 multiply-adds


def cpu_description() -> str:
    """The CPU's model, its core count and the vector flags that decide the kernels' speed."""
    try:
        info = open("/proc/cpuinfo").read().splitlines()
    except OSError:
        return f"unknown CPU, {os.cpu_count()} cores"
    model = next((x.split(":", 1)[1].strip() for x in info if x.startswith("model name")), "unknown CPU")
    flags = next((x.split(":", 1)[1].split() for x in info if x.startswith("flags")), [])
    present = ", ".join(f for f in VECTOR_FLAGS if f in flags) or "none of " + "/".join(VECTOR_FLAGS)
    return f"{model}, {os.cpu_count()} cores ({present})"


def gmac_reference_ms(repeat: int = 31) -> float:
    """The median time (ms) of a float32 product of two 1024 x 1024 matrices, after a warm-up."""
    import numpy as np
    import torch

    g = torch.Generator().manual_seed(0)
    a = torch.randn(REFERENCE_SIZE, REFERENCE_SIZE, generator=g)
    b = torch.randn(REFERENCE_SIZE, REFERENCE_SIZE, generator=g)
    out = torch.empty(REFERENCE_SIZE, REFERENCE_SIZE)
    for _ in range(3):
        torch.mm(a, b, out=out)
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        torch.mm(a, b, out=out)
        times.append(time.perf_counter() - t0)
    return 1000 * float(np.median(times))
