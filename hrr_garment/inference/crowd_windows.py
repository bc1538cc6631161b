"""A crowd's motion windows: each character's last W frames of features and, where the window step
is native, their GRU input gates (:func:`~.gate.frame_gates`), kept per character and as one
array for the whole crowd.

Why one array: stacking each character's frames every push took a millisecond of a 64-character
step. While the same characters are pushed in the same order (a game's every frame) the arrays
slide by one frame, each into a second array of the same shape that then takes its place (one copy;
sliding in place copies through a buffer, twice the memory traffic: 4 MB a frame at 64 characters);
when the crowd changes (a join, a leave, another order, a teleport's restart) they are built again
from the characters' own frames. A push's windows are valid until the push after next.
"""

from __future__ import annotations

from collections import deque

import numpy as np


class CrowdWindows:
    """The crowd's windows (N, W, F) and their frames' gates (N, W, 3H), or None without gates."""

    def __init__(self, window: int):
        self.window = window
        self.keys: tuple | None = None
        self.features: np.ndarray | None = None
        self.gates: np.ndarray | None = None
        self._spare: dict[str, np.ndarray] = {}  # the arrays the next slide writes into, by name

    def start(self) -> tuple[deque, deque]:
        """A new character's own frames: its features and its gates."""
        return deque(maxlen=self.window), deque(maxlen=self.window)

    def push(
        self, keys: tuple, chars: list, features: np.ndarray, gates: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """This frame's rows (``features`` (N, F), ``gates`` (N, 3H) or None) appended to each
        character's own (``chars[i].features``, ``.gates``; a character's first frame repeated
        before its start, as offline causal) -> the crowd's windows and their gates."""
        joined = np.array([not c.features for c in chars])
        for i, c in enumerate(chars):
            for kept, row in ((c.features, features[i]), (c.gates, None if gates is None else gates[i])):
                if row is not None:
                    kept.extend([row] * (self.window - 1 if joined[i] else 0))
                    kept.append(row)
        if keys == self.keys and not joined.any():
            self.features = self._slide("features", self.features, features)
            self.gates = None if self.gates is None else self._slide("gates", self.gates, gates)
        else:
            self.keys = keys
            self.features = np.stack([np.stack(c.features) for c in chars])
            self.gates = None if gates is None else np.stack([np.stack(c.gates) for c in chars])
        return self.features, self.gates

    def _slide(self, name: str, kept: np.ndarray, new: np.ndarray) -> np.ndarray:
        """``kept`` (N, W, ...) one frame on, ``new`` (N, ...) last, in the spare array; ``kept``
        becomes the spare."""
        out = self._spare.get(name)
        if out is None or out.shape != kept.shape or out.dtype != kept.dtype:
            out = np.empty_like(kept)
        out[:, :-1] = kept[:, 1:]
        out[:, -1] = new
        self._spare[name] = kept
        return out
