"""Motion onto a body: a clip on the canonical skeleton played by a body of other proportions.

    on_body = motion_on_body(motion, record)     # record: a body (body.json, or a fitted body)

The joints keep their local rotations (the body's skeleton has the canonical T-pose directions,
:mod:`.fit`), the bones take the body's lengths, and the root's path scales with the legs: a body
whose pelvis stands k times as high as the mannequin's moves it k times as far and as high, so its
feet land where its own stride puts them. A body uniformly k times the mannequin's therefore plays
the clip exactly k times larger (tested).
"""

from __future__ import annotations

import numpy as np

from ..motion.motion import Motion
from ..motion.skeleton import CANONICAL, REST_PELVIS_HEIGHT


def motion_on_body(motion: Motion, body) -> Motion:
    """``motion`` played by ``body`` (anything with ``skeleton`` and ``pelvis_height``: a
    :class:`~.body_file.BodyRecord` or a :class:`~.fit.FittedBody`)."""
    scale = float(body.pelvis_height) / REST_PELVIS_HEIGHT
    return Motion(
        motion.local_rotations,
        motion.root_translation * scale,
        motion.fps,
        source=motion.source,
        source_skeleton=motion.source_skeleton,
        source_height_m=motion.source_height_m,
        skeleton=body.skeleton,
        check_rotations=False,
    )


def played_by(motion: Motion, body) -> Motion:
    """``motion`` on ``body``'s skeleton (``body`` as :func:`motion_on_body` takes it): as it is when
    it already stands on it, played by the body when it is a canonical clip; a ValueError for a clip
    on some other skeleton."""
    if np.allclose(motion.skeleton.offsets, body.skeleton.offsets, atol=1e-6):
        return motion
    if motion.skeleton is CANONICAL:
        return motion_on_body(motion, body)
    raise ValueError(
        "the motion stands on another skeleton than the body's: give the clip on the canonical skeleton"
    )
