"""One character streamed, one pose in and one garment frame out (:class:`AnimationStream`): a
crowd of one (:class:`~.stream.CrowdStream`) with a single character's API."""

from __future__ import annotations

from collections import deque

import numpy as np

from ..motion.motion import Motion
from .modes import Mode
from .run_settings import ResolvedRun
from .stream import CrowdStream


class AnimationStream:
    """One character: one pose in, one garment frame out, causal (no future frames), bounded memory.
    ``push`` equals frame t of ``animator.animate(motion, causal=True)`` (tested to 1e-5)."""

    def __init__(self, animator, run: ResolvedRun, *, rig=None):
        self.crowd = CrowdStream(animator, run, rig=rig)

    @property
    def mode(self) -> Mode:
        return self.crowd.mode

    @property
    def frames(self) -> int:
        chars = self.crowd._characters
        return chars[0].frames if chars else 0

    @property
    def latency_s(self) -> deque:
        """Seconds per push, the last 1,000 (diagnostics)."""
        return self.crowd.timings.latency_s

    @property
    def stage_s(self) -> dict[str, deque]:
        """Seconds per push and stage (features, encoder: motion encoder + gate + code-space decoder,
        decoder: mesh decoder, world, push_out): where a frame's time goes."""
        return self.crowd.timings.stage_s

    def push(
        self,
        pose: Motion | None = None,
        *,
        rotation: np.ndarray | None = None,
        root: np.ndarray | None = None,
    ) -> np.ndarray:
        """A one-frame :class:`Motion` on the canonical skeleton, or raw arrays: ``rotation`` (J, 4)
        quaternions (x, y, z, w), (J, 3) axis-angle or (J, 3, 3) matrices and ``root`` (3,) ->
        (V, 3) world vertices."""
        if pose is not None:
            if rotation is not None or root is not None:
                raise TypeError("push takes a pose or rotation= and root=, not both")
            if not isinstance(pose, Motion):
                raise TypeError(f"pose must be a one-frame Motion, not {type(pose).__name__}")
            return self.crowd.push_motions({0: pose})[0]
        if rotation is None or root is None:
            raise TypeError("push needs a one-frame Motion, or rotation= and root=")
        return self.crowd.push(np.asarray(rotation)[None], np.asarray(root)[None], [0])[0]
