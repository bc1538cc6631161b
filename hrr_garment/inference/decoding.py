"""Running the networks at inference: the denormal switch around a run, and the mesh decoder over
per-frame latents."""

from __future__ import annotations

from contextlib import contextmanager

import numpy as np
import torch

from ..artifacts.bundle import Bundle


@contextmanager
def flush_denormals():
    """Treat denormal floats (< 1.2e-38) as zero while inference runs (the CPU's flush-to-zero
    mode, as game engines run): trained networks produce some, and each product with one takes a
    slow path (it doubled a trained motion encoder's time). Switches it back off on exit (PyTorch's
    default; the current setting cannot be read)."""
    torch.set_flush_denormal(True)
    try:
        yield
    finally:
        torch.set_flush_denormal(False)


def body_frame_vertices(bundle: Bundle, latents: np.ndarray, decoder, batch: int = 64) -> np.ndarray:
    """Decode per-frame latents (T, nodes, C) to body-frame vertices (T, V, 3)
    (:mod:`hrr_garment.motion.frame`; :func:`~hrr_garment.motion.frame.from_body_frame` takes
    them to the world)."""
    out = np.empty((len(latents), bundle.template.num_vertices, 3), np.float32)
    for i in range(0, len(latents), batch):
        out[i : i + batch] = decoder(torch.from_numpy(np.ascontiguousarray(latents[i : i + batch]))).numpy()
    return out
