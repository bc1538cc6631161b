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
        return Inertializer.step_many([self], target[None], [source], None if continuous is None else continuous[None])[0]

    @staticmethod
    def step_many(inerts: list["Inertializer"], targets: np.ndarray, sources: list, continuous: np.ndarray | None = None) -> np.ndarray:
        """:meth:`step` of several inertializers at once (a crowd's characters, each its own state):
        row i is ``inerts[i].step(targets[i], sources[i], continuous[i])``, the same bits (the spring
        is elementwise), in a few array operations for all the rows instead of a dozen per row."""
        split = continuous is not None
        parts = targets - continuous if split else targets
        offset, offset_vel = np.empty_like(targets), np.empty_like(targets)
        same = np.zeros(len(inerts), bool)
        for i, s in enumerate(inerts):
            same[i] = s._prev_target is not None and sources[i] == s._source and split == s._prev_split
            offset[i] = 0.0 if s._offset is None else s._offset
            offset_vel[i] = 0.0 if s._offset_vel is None else s._offset_vel
            if s._prev_target is not None and not same[i]:
                # the old source one frame on (moving as it last did) against the new one (velocity unknown: 0)
                if split == s._prev_split:
                    before, velocity, now = s._prev_part, s._prev_part_vel, parts[i]
                else:
                    before, velocity, now = s._prev_target, s._prev_target_vel, targets[i]
                velocity = velocity if velocity is not None else np.zeros_like(now)
                offset[i] = offset[i] + before + velocity - now
                offset_vel[i] = offset_vel[i] + velocity
        shape = (-1,) + (1,) * (targets.ndim - 1)
        damping = np.array([s._damping for s in inerts]).reshape(shape)
        decay = np.array([s._decay for s in inerts]).reshape(shape)
        j1 = offset_vel + offset * damping
        offset, offset_vel = decay * (offset + j1), decay * (offset_vel - j1 * damping)
        rows = np.flatnonzero(same)
        target_vel = part_vel = None
        if rows.size:
            target_vel = targets[rows] - np.stack([inerts[i]._prev_target for i in rows])
            part_vel = target_vel if not split else parts[rows] - np.stack([inerts[i]._prev_part for i in rows])
        at = {int(i): j for j, i in enumerate(rows)}
        for i, s in enumerate(inerts):
            j = at.get(i)
            s._offset, s._offset_vel = offset[i], offset_vel[i]
            s._prev_target_vel = None if j is None else target_vel[j]
            s._prev_part_vel = None if j is None else part_vel[j]
            s._prev_target, s._prev_part, s._prev_split, s._source = targets[i], parts[i], split, sources[i]
        return targets + offset


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
    return inertialize_many([inert], latent[None], np.array([retrieved]), source[None], [frame],
                            continuous=None if continuous is None else continuous[None])[0]


def inertialize_many(inerts: list[Inertializer], latents: np.ndarray, retrieved: np.ndarray, sources: np.ndarray,
                     frames: list[int], continuous: np.ndarray | None = None) -> np.ndarray:
    """:func:`inertialize` for several paths at once (a crowd's characters, row i on ``inerts[i]``,
    at its clip frame ``frames[i]``): (n, nodes, C) float64, row i what :func:`inertialize` gives."""
    ids = [source_id(bool(r), s - np.array([0, f]) if r else s) for r, s, f in zip(retrieved, sources, frames)]
    return Inertializer.step_many(inerts, latents.astype(np.float64), ids,
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
