"""From per-window latents to per-frame latents.

Offline, each frame's latent is the weighted mean of the windows that cover it, with weights that
peak at window centres (sin^2), so a change of source between windows is a cross-fade, continuous
in position and velocity. Causal, frame t takes the last frame of the window ending at t, and a
change of source (mode, or retrieved clip) is removed by inertialization: the jump between the old
and the new source (in position and velocity) becomes an offset that decays to zero as a
critically damped spring over about ``blend`` frames.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .gate import WindowChoice


def window_weights(size: int) -> np.ndarray:
    """Blend weight of each position in a window: sin^2, highest at the centre, never zero."""
    return np.sin(np.pi * (np.arange(size) + 0.5) / size) ** 2


def blend_windows(latents: np.ndarray, frames: int) -> np.ndarray:
    """Per-frame weighted mean of overlapping windows: latents (N, W, ...) with window i covering
    frames i .. i + W - 1 -> (frames, ...)."""
    n, w = latents.shape[:2]
    weights = window_weights(w)
    total = np.zeros((frames, *latents.shape[2:]), np.float64)
    norm = np.zeros(frames)
    for k in range(w):
        total[k:k + n] += weights[k] * latents[:, k]
        norm[k:k + n] += weights[k]
    return (total / norm.reshape(-1, *([1] * (latents.ndim - 2)))).astype(np.float32)


@dataclass
class Inertializer:
    """Removes jumps when the latent source switches: the output is the current source plus an
    offset that absorbs each switch's jump in position and velocity (the old source's value and
    velocity, extrapolated one frame, minus the new one's) and decays to zero as a critically damped
    spring with a half-life of ``frames / 3`` frames (1 % of a jump is left after about ``frames``
    + 4 frames). Offsets of switches that come before the last one has decayed add up and decay
    together, so a source that changes every frame (retrieval picking another clip each window) is
    smoothed, not extrapolated: the output stays within a few jumps of the sources. (A quintic that
    restarted from the output's own velocity at every switch ran away on such streams: 720 mm on
    causal retrieval of real clips.)

    A target with a ``continuous`` part (one source whatever the match: the regression under a
    residual) jumps only by the rest at a switch between two such targets; the continuous part is
    followed as it is (extrapolated at every change of match, it lagged: causal PVE 33.8 against the
    regression's 31.7 mm). Between a target with and one without, the whole jumps."""

    frames: int = 6
    _offset: np.ndarray | None = None
    _offset_vel: np.ndarray | None = None
    _source: tuple = field(default=(None,))
    _prev_target: np.ndarray | None = None
    _prev_target_vel: np.ndarray | None = None
    _prev_part: np.ndarray | None = None  # the previous target less its continuous part (or all of it)
    _prev_part_vel: np.ndarray | None = None
    _prev_split: bool = False  # whether the previous target had a continuous part

    def __post_init__(self) -> None:
        # one frame of a critically damped spring (exact) with half-life frames / 3: fixed per stream
        self._damping = 2.0 * np.log(2.0) / max(self.frames / 3.0, 1e-6)
        self._decay = float(np.exp(-self._damping))

    def step(self, target: np.ndarray, source: tuple, continuous: np.ndarray | None = None) -> np.ndarray:
        """target: this frame's latent from ``source`` (a hashable id of where it came from);
        ``continuous``: its part that does not change with the source (see the class docstring)."""
        split = continuous is not None
        part = target - continuous if split else target
        if self._offset is None:
            self._offset, self._offset_vel = np.zeros_like(target), np.zeros_like(target)
        same = self._prev_target is not None and source == self._source and split == self._prev_split
        if self._prev_target is not None and not same:
            # the old source one frame on (moving as it last did) against the new one (velocity unknown: 0)
            if split == self._prev_split:
                before, velocity, now = self._prev_part, self._prev_part_vel, part
            else:
                before, velocity, now = self._prev_target, self._prev_target_vel, target
            velocity = velocity if velocity is not None else np.zeros_like(target)
            self._offset = self._offset + before + velocity - now
            self._offset_vel = self._offset_vel + velocity
        damping, decay = self._damping, self._decay
        j1 = self._offset_vel + self._offset * damping
        self._offset, self._offset_vel = decay * (self._offset + j1), decay * (self._offset_vel - j1 * damping)
        self._prev_target_vel = target - self._prev_target if same else None
        self._prev_part_vel = part - self._prev_part if same else None
        self._prev_target, self._prev_part, self._prev_split, self._source = target, part, split, source
        return target + self._offset


def source_id(retrieved: bool, source: np.ndarray) -> tuple:
    """Consecutive causal windows from one retrieved clip advance by one frame each: same id."""
    return ("regression",) if not retrieved else ("retrieval", int(source[0]), int(source[1]))


# causal paths inertialize only a residual's departure at a change of match (decision 0024); False:
# the whole latent, as hrr_garment did before 2026-11-27 (tests reproduce its files with it)
DEPARTURE_ONLY = True


def inertialize(inert: Inertializer, latent: np.ndarray, retrieved: bool, source: np.ndarray, frame: int,
                continuous: np.ndarray | None = None) -> np.ndarray:
    """One causal frame of one latent path: ``latent`` (nodes, C), the last frame of the window
    ending at clip frame ``frame``; a retrieved window's ``source`` (database sequence, start) is
    taken back to that clip's frame 0 first, so consecutive windows of one clip keep one id.
    ``continuous``: the part of ``latent`` that does not change with the source (the regression
    under a residual, :attr:`~.gate.WindowChoice.continuous`): followed as it is, only the rest
    inertialized (:class:`Inertializer`)."""
    src = source - np.array([0, frame]) if retrieved else source
    return inert.step(latent.astype(np.float64), source_id(bool(retrieved), src),
                      continuous=None if continuous is None or not DEPARTURE_ONLY else continuous.astype(np.float64))


def latent_sources(choice: WindowChoice) -> tuple[np.ndarray, np.ndarray]:
    """The latents a causal path inertializes and whether each window's change with its match
    (:attr:`~.gate.WindowChoice.follows_match`)."""
    return choice.latents, choice.follows_match


def causal_latents(choice: WindowChoice, blend: int = 6) -> np.ndarray:
    """Frame t's latent = the last frame of the window ending at t, made continuous across source
    changes by :class:`Inertializer`. ``choice`` has one window per frame."""
    latents, retrieved = latent_sources(choice)
    inert = Inertializer(blend)
    out = np.empty((len(latents), *latents.shape[2:]), np.float32)
    for t in range(len(out)):
        out[t] = inertialize(inert, latents[t, -1], retrieved[t], choice.match[t], t,
                             continuous=None if choice.continuous is None else choice.continuous[t, -1])
    return out
