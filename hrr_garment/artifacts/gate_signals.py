"""What the hybrid's gate thresholds: a *doubt* about retrieving, per window (retrieve where the
doubt is below tau).

- ``entropy``: the motion code's entropy, the paper's switch: how unsure the motion encoder is.
- ``similarity``: one minus the match's code similarity: how many groups the retrieved window's
  garment code fails to share with the motion code.
- ``distance``: the match's motion distance, the RMS difference of the standardised motion windows
  of the query and the retrieved window: whether the database really holds this motion.

The last two judge the match itself rather than the encoder's confidence (and need the database
searched for every window). Numpy only, so the command lines can list the signals cheaply.
"""

from __future__ import annotations

import numpy as np

#: the signals the hybrid's gate can threshold (see the module docstring); "entropy" is the paper's
GATE_SIGNALS = ("entropy", "similarity", "distance")


def check_gate_signal(signal: str) -> str:
    """``signal`` if it is one of :data:`GATE_SIGNALS`; a ValueError naming them otherwise."""
    if signal not in GATE_SIGNALS:
        raise ValueError(f"unknown gate signal {signal!r}; choose one of {', '.join(GATE_SIGNALS)}")
    return signal


def gate_doubt(
    signal: str, entropy: np.ndarray, similarity: np.ndarray | None = None, distance: np.ndarray | None = None
) -> np.ndarray:
    """Per-window doubt about retrieving (lower: retrieve) from the gate ``signal``'s inputs: the
    motion-code entropy (N,), the match's code similarity (N,) or its motion distance (N,)."""
    if signal == "entropy":
        return np.asarray(entropy, np.float64)
    if signal == "similarity" and similarity is not None:
        return 1.0 - np.asarray(similarity, np.float64)
    if signal == "distance" and distance is not None:
        return np.asarray(distance, np.float64)
    check_gate_signal(signal)
    raise ValueError(f"the {signal!r} gate needs the match's {signal}")
