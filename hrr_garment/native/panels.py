"""The dense products' right-hand matrices in the kernels' panel layout (``linear_rows`` in
``kernels.c``), shared by the decoder's factored block and the code space's window step."""

from __future__ import annotations

import numpy as np

PANEL = 64  # PANEL in hrr_native.h


def pack_panels(wt: np.ndarray) -> np.ndarray:
    """A dense product's right-hand matrix (in, out) in the kernels' layout (``linear_rows``):
    panels of PANEL columns, (panels, in, PANEL), zero-padded to whole panels."""
    inp, out = wt.shape
    panels = np.pad(wt, [(0, 0), (0, -out % PANEL)]).reshape(inp, -1, PANEL).transpose(1, 0, 2)
    return np.ascontiguousarray(panels, np.float32)
