"""Hybrid inference: a motion in, an animated garment out (paper 3.5, DESIGN 7).

Offline (default): features of the whole clip -> every window (stride 1, W frames, centred
coverage) -> motion encoder -> code distribution -> per window, retrieval from the database when
its entropy is below tau, else regression by the decoder -> per frame, the overlapping windows'
latents blended with weights that peak at window centres (sin^2, so a window fades in and out
smoothly and a change of source between windows is a cross-fade, continuous in position and
velocity) -> autoencoder decoder -> heading frame to world -> collision push-out.

Causal (``causal=True``, and the streaming API): frame t sees only frames <= t. Its window is the
W frames ending at t (the clip's first frame repeated before the start); its garment latent is that
window's last frame. When the source changes (mode, or retrieved clip) the jump is removed by
inertialization: the offset between the previous output and the new source (and between their
velocities) decays to zero over ``blend`` frames with a quintic that has zero velocity and
acceleration at its end, so position and velocity stay continuous. Streaming equals offline causal.
"""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np
import torch

from ..data.windows import sequence_windows
from ..motion.features import motion_features
from ..motion.frame import from_body_frame
from ..motion.motion import Motion
from ..artifacts.bundle import Bundle
from ..models.codes import encode_motion

MODES = ("hybrid", "regression", "retrieval", "naive-nn")


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


def window_weights(size: int) -> np.ndarray:
    """Blend weight of each position in a window: sin^2, highest at the centre, never zero."""
    return np.sin(np.pi * (np.arange(size) + 0.5) / size) ** 2


def to_world(points: np.ndarray, motion: Motion) -> np.ndarray:
    """Body-frame points (T, N, 3), as the models output them, to world coordinates
    (:func:`~hrr_garment.motion.frame.from_body_frame`)."""
    return from_body_frame(points, motion)


def pair_features(previous: Motion | None, current: Motion) -> np.ndarray:
    """Features (124,) of the one-frame ``current`` given the frame before it (None at the start:
    the frame is repeated, so velocities are zero)."""
    before = current if previous is None else previous
    if before.num_frames > 1:
        before = before.slice(before.num_frames - 1, before.num_frames)
    current.global_rotations  # noqa: B018 - computes (and caches) the pose's kinematics, reused by the pair and the next push
    pair = Motion.concatenate([before, current]) if previous is not None else current
    return causal_features(pair)[-1]


def causal_features(motion: Motion) -> np.ndarray:
    """Features as a stream sees them: frame t from frames t-1 and t only (frame 0: zero
    velocities). Equal to :func:`motion_features` from frame 1 on. In C where compiled (the same
    formulas; a stream computes them per frame), else numpy."""
    from .. import native
    from ..motion.skeleton import FEATURE_JOINTS

    lib = native.load_kernel()
    if lib is not None:
        return native.causal_features(lib, motion.global_rotations, motion.joint_positions, FEATURE_JOINTS, motion.fps)
    if motion.num_frames == 1:
        return motion_features(Motion.concatenate([motion, motion]))[-1:]
    feats = motion_features(motion)
    feats[0] = motion_features(Motion.concatenate([motion.slice(0, 1)] * 2))[-1]
    return feats


@dataclass
class WindowChoice:
    """What the gate decided for each window (N windows)."""

    latents: np.ndarray  # (N, W, nodes, C) chosen garment latents ((N, 1, nodes, C): last frames only)
    retrieved: np.ndarray  # (N,) bool
    entropy: np.ndarray  # (N,) motion-code entropy
    source: np.ndarray  # (N, 2) int32 (database sequence index, start frame) of retrieved windows, else -1


def choose_windows(bundle: Bundle, motion_windows: np.ndarray, mode: str, tau: float,
                   exclude: np.ndarray | None = None, last_frame: bool = False,
                   step: torch.nn.Module | None = None) -> WindowChoice:
    """Run the motion encoder on raw feature windows (N, W, F) and pick each window's latents
    (with ``last_frame``, only the last frame's: all that causal inference blends). ``step``:
    see :func:`encode_motion`."""
    if mode not in MODES:
        raise ValueError(f"unknown mode {mode!r}; choose one of {', '.join(MODES)}")
    db = bundle.database
    enc = encode_motion(bundle.codespace, bundle.motion_stats, bundle.latent_stats, motion_windows,
                        regression=mode in ("hybrid", "regression"), last_frame=last_frame, step=step)
    n = len(enc.entropy)
    retrieved = {"hybrid": enc.entropy < tau, "regression": np.zeros(n, bool)}.get(mode, np.ones(n, bool))
    frames = 1 if last_frame else db.latents.shape[1]
    latents = enc.regression.copy() if enc.regression is not None else np.empty((n, frames, *db.latents.shape[2:]), np.float32)
    source = np.full((n, 2), -1, np.int32)
    if retrieved.any():
        rows = np.flatnonzero(retrieved)
        ex = None if exclude is None else np.asarray(exclude)[rows]
        if mode == "naive-nn":
            match = db.nearest_motion(enc.standardised[rows], ex)
        else:
            match, _ = db.search(enc.codes[rows], ex)
        latents[rows] = db.latents[match, -frames:]
        source[rows] = np.stack([db.sequence[match], db.start[match]], 1)
    return WindowChoice(latents, retrieved, enc.entropy, source)


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
    """Removes jumps when the latent source switches: keeps the offset (and its velocity) between
    the last output and the new source, and lets it decay to zero over ``frames`` frames along a
    quintic with zero velocity and acceleration at the end (continuous position and velocity)."""

    frames: int = 6
    _prev: np.ndarray | None = None
    _prev_vel: np.ndarray | None = None
    _offset: np.ndarray | None = None
    _offset_vel: np.ndarray | None = None
    _age: int = 0
    _source: tuple = field(default=(None,))
    _prev_target: np.ndarray | None = None

    def step(self, target: np.ndarray, source: tuple) -> np.ndarray:
        """target: this frame's latent from ``source`` (a hashable id of where it came from)."""
        target_vel = target - self._prev_target if self._prev_target is not None and source == self._source else None
        if self._prev is not None and source != self._source:
            vel = target_vel if target_vel is not None else np.zeros_like(target)
            prev_vel = self._prev_vel if self._prev_vel is not None else np.zeros_like(target)
            self._offset = self._prev + prev_vel - target  # where the old motion would have gone
            self._offset_vel = prev_vel - vel
            self._age = -1
        out = target.copy()
        if self._offset is not None:
            self._age += 1
            t = min(1.0, self._age / self.frames)
            if t < 1.0:
                x0, v0, T = self._offset, self._offset_vel * self.frames, 1.0
                # quintic from (x0, v0, a0 = 0) to (0, 0, 0) on [0, 1]
                a = -(6 * x0 + 3 * v0 * T)
                b = 15 * x0 + 8 * v0 * T
                c = -(10 * x0 + 6 * v0 * T)
                out += x0 + v0 * t + c * t**3 + b * t**4 + a * t**5
            else:
                self._offset = None
        self._prev_vel = out - self._prev if self._prev is not None else np.zeros_like(out)
        self._prev, self._source, self._prev_target = out, source, target
        return out


def source_id(retrieved: bool, source: np.ndarray) -> tuple:
    """Consecutive causal windows from one retrieved clip advance by one frame each: same id."""
    return ("regression",) if not retrieved else ("retrieval", int(source[0]), int(source[1]))


def causal_latents(choice: WindowChoice, blend: int = 6) -> np.ndarray:
    """Frame t's latent = the last frame of the window ending at t, made continuous across source
    changes by :class:`Inertializer`. ``choice`` has one window per frame."""
    inert = Inertializer(blend)
    out = np.empty((len(choice.latents), *choice.latents.shape[2:]), np.float32)
    for t in range(len(out)):
        src = choice.source[t] - np.array([0, t]) if choice.retrieved[t] else choice.source[t]
        out[t] = inert.step(choice.latents[t, -1].astype(np.float64), source_id(bool(choice.retrieved[t]), src))
    return out


def causal_windows(features: np.ndarray, size: int) -> np.ndarray:
    """(T, F) -> (T, W, F): window t holds frames t-W+1 .. t, frame 0 repeated before the start."""
    padded = np.concatenate([np.repeat(features[:1], size - 1, 0), features])
    return np.ascontiguousarray(sequence_windows(padded, size))


def heading_vertices(bundle: Bundle, latents: np.ndarray, decoder, batch: int = 64) -> np.ndarray:
    """Decode per-frame latents (T, nodes, C) to heading-frame vertices (T, V, 3)."""
    out = np.empty((len(latents), bundle.template.num_vertices, 3), np.float32)
    for i in range(0, len(latents), batch):
        out[i:i + batch] = decoder(torch.from_numpy(np.ascontiguousarray(latents[i:i + batch]))).numpy()
    return out
