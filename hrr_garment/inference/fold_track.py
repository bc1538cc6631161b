"""The detail mode's fold track: which simulated frames lend their folds to each output frame.

Every window proposes its best match's frame for the output frame (offline the centred window's,
causal the last one's). Taking each frame's proposal as it comes would switch folds almost every
frame (the matches of neighbouring windows come from different clips), and a blend of the
proposals averages the folds away. The track does what motion matching does: a playhead in one
database sequence that plays forward one frame per frame while the proposals agree with it, jumps to
the current proposal when they have disagreed for ``hold`` frames (or its sequence ends), and
cross-fades the old playhead's folds out over ``fade`` frames after a jump. The same step runs
offline, causal and streaming, so a stream equals the causal track.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

FOLD_HOLD = 8  # frames the proposals may disagree with the playhead before it jumps
FOLD_FADE = 6  # frames over which the folds of the frame jumped from fade out
FOLD_SLACK = 3  # a proposal this many frames or fewer from the playhead, in its sequence, agrees


@dataclass
class FoldTrack:
    """One animation's playhead; :meth:`step` once per output frame."""

    offsets: np.ndarray  # (S + 1,) the fold store's: sequence s's frames are rows offsets[s] .. offsets[s + 1] - 1
    hold: int = FOLD_HOLD
    fade: int = FOLD_FADE
    slack: int = FOLD_SLACK
    sequence: int = -1
    frame: int = 0
    disagreed: int = 0  # frames since a proposal last agreed (or since the jump)
    old_sequence: int = -1
    old_frame: int = 0
    fading: int = 0  # frames of the old playhead's fade left

    def __post_init__(self) -> None:
        self.lengths = np.diff(self.offsets)

    def step(self, sequence: int, frame: int) -> tuple[np.ndarray, np.ndarray]:
        """This frame's proposal (database sequence, frame) -> the fold store rows (2,) of the
        playhead and of the one fading out, and their weights (2,) (0 when none; they sum to 1)."""
        sequence, frame = int(sequence), int(frame)
        if self.sequence < 0:
            self.sequence, self.frame = sequence, frame
        else:
            self.frame += 1
            self.old_frame = min(self.old_frame + 1, int(self.lengths[self.old_sequence]) - 1) if self.fading else 0
            agrees = sequence == self.sequence and abs(frame - self.frame) <= self.slack
            self.disagreed = 0 if agrees else self.disagreed + 1
            if self.frame >= self.lengths[self.sequence] or self.disagreed >= self.hold:
                self.old_sequence, self.old_frame = self.sequence, min(self.frame, int(self.lengths[self.sequence]) - 1)
                self.sequence, self.frame, self.disagreed, self.fading = sequence, frame, 0, self.fade
        old = self.fading / (self.fade + 1.0)
        here = self.offsets[self.sequence] + self.frame
        rows = np.array([here, self.offsets[self.old_sequence] + self.old_frame if self.fading else here], np.int64)
        self.fading = max(self.fading - 1, 0)
        return rows, np.array([1.0 - old, old])


def offline_proposals(source: np.ndarray, frames: int, window: int) -> np.ndarray:
    """Offline: frame t's proposal is its frame in the match of the window centred on it (window
    i covers frames i .. i + W - 1). ``source`` (N, 2) (database sequence, start) -> (frames, 2)."""
    i = np.clip(np.arange(frames) - window // 2, 0, len(source) - 1)
    return np.stack([source[i, 0], source[i, 1] + np.arange(frames) - i], 1)


def causal_proposals(source: np.ndarray, window: int) -> np.ndarray:
    """Causal: frame t's proposal is the last frame of the match of the window ending at t."""
    return np.stack([source[:, 0], source[:, 1] + window - 1], 1)


def track_folds(proposals: np.ndarray, offsets: np.ndarray, **settings: int) -> tuple[np.ndarray, np.ndarray]:
    """(T, 2) proposals -> the fold store rows (T, 2) and weights (T, 2) of a :class:`FoldTrack`
    over them (``offsets``: the store's; ``settings``: its hold, fade or slack, for analysis)."""
    track = FoldTrack(offsets, **settings)
    steps = [track.step(sequence, frame) for sequence, frame in proposals]
    return np.array([r for r, _ in steps], np.int64).reshape(-1, 2), np.array([w for _, w in steps]).reshape(-1, 2)
