"""A crowd's state between pushes (:class:`~.stream.CrowdStream`): each character's, the push's
keys checked, and where a push's time goes."""

from __future__ import annotations

import warnings
from collections import deque
from collections.abc import Hashable, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError, TeleportWarning, user_stacklevel
from ..models.sampler import SampleTrack
from ..motion.limits import MAX_ROOT_SPEED
from .fold_track import FoldTrack, FollowedFolds
from .lod import LodState
from .run_settings import MAX_SEED, whole_number

# a push's time by groups of the frame path's stages (frame_path.STAGES): features (1-2), encoder
# (3-5: the window step, blending, swing), decoder (6-7), world (8), push_out (9)
STREAM_STAGES = ("features", "encoder", "decoder", "world", "push_out")


@dataclass
class CrowdCharacter:
    """One character's streaming state."""

    features: deque  # its window's W frames' raw features (crowd_windows.CrowdWindows)
    gates: deque  # those frames' GRU input gates, where the window step is native (gate.frame_gates)
    inertia: int  # its row in the crowd's Inertializer
    fold_track: FoldTrack | None = None  # the detail mode's playhead in the database's folds
    followed: FollowedFolds | None = None  # its folds as followed in time (fold_track.follow_folds)
    previous: tuple[np.ndarray, np.ndarray] | None = (
        None  # its last pose: global rotations and joint positions
    )
    memory: np.ndarray | None = None  # its motion memory's state (rows, 64), when the model has one
    root: np.ndarray | None = None  # its last pushed pelvis position (teleports restart it)
    frames: int = 0
    lod: LodState = field(default_factory=LodState)  # its level of detail's held step and decoder fade
    swing_mean: np.ndarray | None = None  # (nodes, C) its latents' recent course (inference/swing.py)
    # its last latents, lagged (nodes, C), and its stillness clock (inference/settle.py)
    settled: tuple[np.ndarray, float] | None = None
    sample: SampleTrack | None = None  # the sample mode's draw as it goes on (models/sampler.py)


def character_seed(seed) -> int:
    """``seed``, a character's own seed for the sample mode's draw, as an int; a ValueError naming the
    range unless it is a whole number in [0, MAX_SEED], as the run's seed is."""
    return whole_number(seed, "seed", bounds=(0, MAX_SEED))


def check_keys(keys: list, count: int) -> None:
    """An InputError unless ``keys`` are ``count`` distinct ids, one per pushed pose."""
    if len(keys) != count or len(set(keys)) != len(keys):
        raise InputError(
            "push",
            f"{count} poses need as many distinct keys, got {len(keys)} keys ({len(set(keys))} distinct)",
        )


def teleported(
    keys: Sequence[Hashable],
    last_roots: Sequence[np.ndarray | None],
    roots: np.ndarray,
    *,
    fps: float,
) -> list[int]:
    """The indices into ``keys`` of the characters whose pelvis moved faster than
    :data:`~hrr_garment.motion.limits.MAX_ROOT_SPEED` from its last pushed position (``last_roots``,
    None for a character not pushed before) to ``roots`` (N, 3): respawns, each warned of with a
    :class:`~hrr_garment.errors.TeleportWarning` (both crowds restart them: cloth dragged across the
    jump would be what no simulation gives), each warning pointing at the user's call."""
    known = [i for i, last in enumerate(last_roots) if last is not None]
    if not known:
        return []
    last = np.stack([last_roots[i] for i in known])
    jump = np.linalg.norm(np.asarray(roots, np.float64)[known] - last, axis=1)
    out = []
    for j in np.flatnonzero(jump * fps > MAX_ROOT_SPEED):
        out.append(known[j])
        warnings.warn(
            f"character {keys[known[j]]!r}: the pelvis moved {jump[j]:.3g} m in one frame "
            f"(over {MAX_ROOT_SPEED:g} m/s); taken as a teleport, its garment starts afresh there",
            TeleportWarning,
            stacklevel=user_stacklevel(),
        )
    return out


@dataclass
class CrowdTimings:
    """Per push: its latency and each stage's seconds (the last 1,000 pushes)."""

    latency_s: deque = field(default_factory=lambda: deque(maxlen=1000))
    stage_s: dict = field(default_factory=lambda: {k: deque(maxlen=1000) for k in STREAM_STAGES})
