"""A capture's leading reference frames: poses a conversion puts before the motion, dropped.

CMU's MotionBuilder-friendly BVH files begin with a T-pose (every one of subjects 01-09's 97
clips, and the shared 02_01 and 131 clips), some with several, some at another place than the
capture: the first step to the motion turns a joint 78-172 degrees in 1/120 s, or moves the root
tens of metres a second. Played, that is a body snapping from a T-pose into the motion in one
frame, which no cloth survives (36 of the 314 sequences of the first CMU build were refused at
their first frames for it). No human joint turns faster than about 2,000 degrees a second (the
Bandai-Namco library's fastest first steps: 1,930), so a step faster than :data:`MAX_TURN_DEG_S`,
or a root faster than :data:`MAX_ROOT_M_S`, within the first :data:`LEAD_S` is a cut between a
reference pose and the motion, and the frames before the last such cut are dropped.
"""

from __future__ import annotations

import numpy as np

MAX_TURN_DEG_S = 4000.0
MAX_ROOT_M_S = 15.0
LEAD_S = 0.25  # reference frames come first: a fast step later is motion (or a glitch the checks catch)


def leading_reference_frames(local_rotations: np.ndarray, root_m: np.ndarray, fps: float) -> int:
    """How many leading frames are reference poses, not motion (0 where none): the frames before the
    last cut within the first :data:`LEAD_S` (module docstring). ``local_rotations`` (T, J, 3, 3),
    ``root_m`` (T, 3) in metres."""
    lead = min(len(local_rotations) - 1, max(1, int(round(LEAD_S * fps))))
    if lead < 1:
        return 0
    rot = local_rotations[: lead + 1].astype(np.float64)
    cos = (np.trace(np.swapaxes(rot[:-1], -1, -2) @ rot[1:], axis1=-2, axis2=-1) - 1.0) / 2.0
    turn = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))).max(1) * fps
    root = np.linalg.norm(np.diff(root_m[: lead + 1], axis=0), axis=1) * fps
    cuts = np.flatnonzero((turn > MAX_TURN_DEG_S) | (root > MAX_ROOT_M_S))
    return int(cuts[-1]) + 1 if len(cuts) else 0
