"""A source skeleton for streamed poses: an engine's rig, retargeted pose by pose as its files are.

    rig = StreamRig.from_bvh("hero_idle.bvh")        # the rig's skeleton, joint map and calibration
    crowd = animator.crowd(rig=rig)
    vertices = crowd.push(rotations, roots)          # (N, J, 4) in the rig's joints, roots in its units

A file is retargeted as a whole clip, and two things there come from the clip itself
(:mod:`.retarget`): the rig's constant roll about each bone, for rigs whose zero pose does not
stand (Bandai-Namco's), and the floor the feet stand on. A stream sees one pose at a time, so both
are measured once on a calibration clip on the same rig (by default the BVH the rig is read from)
and then held fixed. Poses from that very clip therefore stream exactly as the file animates
(tested); other clips on the rig get the same roll and floor.

Rotations are local to each joint's parent in the rig's own joint order; non-root joints keep their
rest offsets (the BVH's OFFSET); roots are in the file's length unit, as the rig's files have them.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import MotionError
from .bvh_motion import bvh_source
from .motion import FPS, Motion
from .poses import check_roots, rotations_to_matrices
from .retarget import (
    RetargetCalibration,
    SourceMotion,
    calibrate_retarget,
    check_source,
    retarget,
    standing_height_from_legs,
)
from .skeleton import forward_kinematics


@dataclass(frozen=True)
class StreamRig:
    """A source skeleton (names, parents, rest offsets in metres), its joint map onto the canonical
    skeleton, the metres per unit of its roots and the calibration of its retargeting."""

    names: list[str]
    parents: list[int]
    offsets: np.ndarray  # (J, 3) metres
    rest_positions: np.ndarray  # (J, 3) metres
    mapping: dict[str, int]  # canonical joint name -> rig joint index
    scheme: str
    unit_scale: float  # metres per unit of the roots
    calibration: RetargetCalibration
    source: str

    @classmethod
    def from_bvh(
        cls,
        path: str | Path,
        unit_scale: float | None = None,
        joint_map: dict | None = None,
        calibration_clip: str | Path | None = None,
    ) -> "StreamRig":
        """The rig of a BVH file (its joint names resolved as :func:`~.io.load_motion` does, the
        unit detected unless given), calibrated on ``calibration_clip`` (default: the same file)."""
        path = Path(path)
        rig, scheme, mapping, scale = bvh_source(
            path, unit_scale, joint_map
        )  # the skeleton and unit, read once
        calibration = (
            rig if calibration_clip is None else bvh_source(Path(calibration_clip), scale, joint_map)[0]
        )
        if list(calibration.names) != list(rig.names) or list(calibration.parents) != list(rig.parents):
            raise MotionError(calibration_clip, f"is not on the rig of {path}: its joints differ")
        rest = (
            rig.rest_positions
        )  # metres; a joint's offset is its rest position less its parent's (the root's is unused)
        offsets = rest - rest[[max(p, 0) for p in rig.parents]]
        return cls(
            list(rig.names),
            list(rig.parents),
            offsets,
            rest,
            mapping,
            scheme,
            scale,
            calibrate_retarget(calibration, mapping),
            str(path),
        )

    @property
    def num_joints(self) -> int:
        return len(self.names)

    def to_canonical(
        self, rotations: np.ndarray, roots: np.ndarray, quaternion_order: str = "xyzw"
    ) -> Motion:
        """N poses on this rig (see :mod:`.poses` for the rotation forms) -> an N-frame canonical
        :class:`Motion`, retargeted with the rig's calibration."""
        local = rotations_to_matrices(rotations, self.num_joints, quaternion_order, source=self.source)
        root = check_roots(roots, len(local), self.source) * self.unit_scale
        g_rot, g_pos = forward_kinematics(local, root, self.offsets, parents=tuple(self.parents))
        src = SourceMotion(
            self.names,
            self.parents,
            self.rest_positions,
            global_rotations=g_rot,
            global_positions=g_pos,
            fps=FPS,
            path=self.source,
        )
        check_source(src)
        canon_local, canon_root = retarget(src, self.mapping, ground=True, calibration=self.calibration)
        return Motion(
            canon_local,
            canon_root,
            FPS,
            source=self.source,
            source_skeleton=self.scheme,
            source_height_m=standing_height_from_legs(self.rest_positions, self.mapping),
        )
