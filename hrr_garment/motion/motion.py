"""`Motion`: a clip on the canonical skeleton (local rotations + root translation at a frame rate)."""

from __future__ import annotations

from dataclasses import InitVar, dataclass, field
from functools import cached_property

import numpy as np

from ..errors import MotionError
from .limits import ROTATION_TOLERANCE
from .resample import frame_chunks
from .rotations import rotation_matrix_error
from .skeleton import (
    CANONICAL,
    HEAD_TOP_ABOVE_HEAD_JOINT,
    JOINT_INDEX,
    MIRROR_JOINTS,
    REST_PELVIS_HEIGHT,
    Skeleton,
    forward_kinematics,
    sole_heights,
    sole_points,
)

FPS = 30.0  # the internal frame rate


MIN_FPS, MAX_FPS = 1.0, 1000.0  # frame rates a motion may have (capture runs 24-240)
MAX_TRANSLATION_M = (
    1.0e4  # how far from the origin a pelvis may go: float32 vertices keep millimetres within it
)


def check_local_rotations(
    rotations: np.ndarray, joint_names: list[str] | tuple[str, ...], source: object
) -> None:
    """Refuse a (T, J, 3, 3) local rotation that is not one (a scale, a reflection, zeros), naming
    its frame and joint and ``source`` (a file or a clip), in passes of frames (hours of them fit)."""
    for start, stop in frame_chunks(len(rotations)):
        error = rotation_matrix_error(rotations[start:stop].astype(np.float64))
        if (error > ROTATION_TOLERANCE).any():
            frame, joint = np.unravel_index(int(np.argmax(error)), error.shape)
            raise MotionError(
                source,
                f"local rotation of frame {start + frame}, joint {joint_names[joint]} is not "
                f"a rotation matrix (off by {error.max():.3g}: a scale, a reflection or zeros)",
            )


def _frozen(values, dtype) -> np.ndarray:
    """A read-only, C-contiguous view (a copy where the type or layout differs) of ``values``."""
    out = np.ascontiguousarray(values, dtype=dtype).view()
    out.flags.writeable = False
    return out


@dataclass
class Motion:
    """A motion on the canonical skeleton.

    local_rotations: (T, 22, 3, 3) float32 parent-relative rotations (SMPL joint order).
    root_translation: (T, 3) float64 world position of the pelvis joint, metres, Y up.
    fps: frames per second.
    source: where it came from (a path or a procedural kind and seed).
    source_skeleton: the naming scheme detected on input ("canonical" for native/procedural).
    source_height_m: standing height of the source skeleton, metres.
    """

    local_rotations: np.ndarray
    root_translation: np.ndarray
    fps: float = FPS
    source: str = ""
    source_skeleton: str = "canonical"
    source_height_m: float = REST_PELVIS_HEIGHT + 0.60 + HEAD_TOP_ABOVE_HEAD_JOINT
    skeleton: Skeleton = field(default=CANONICAL, repr=False)
    # False only for rotations that are rotations by construction (a slice of a checked Motion, a
    # conversion from quaternions or angles): the check costs a stream ~3 us a character a frame
    check_rotations: InitVar[bool] = True

    def __post_init__(self, check_rotations: bool = True) -> None:
        name = self.source or "motion"
        for label, values in (
            ("local rotations", self.local_rotations),
            ("root translation", self.root_translation),
        ):
            kind = np.asarray(values).dtype.kind
            if kind not in "iuf":  # complex, bool, text and objects would be cast with a warning at best
                raise MotionError(
                    name, f"{label} have dtype {np.asarray(values).dtype}; expected real numbers"
                )
        # read-only views: a Motion changed after it was checked (and after its forward kinematics
        # were cached) would animate whatever was put in; build a new one instead
        self.local_rotations = _frozen(self.local_rotations, np.float32)
        # float64: world positions far from the origin keep millimetre-exact velocities.
        self.root_translation = _frozen(self.root_translation, np.float64)
        self.validate()
        if check_rotations:
            self._check_rotations(name)

    def _check_rotations(self, name: str) -> None:
        check_local_rotations(self.local_rotations, self.skeleton.names, name)

    def validate(self) -> None:
        name = self.source or "motion"
        t = self.local_rotations.shape[0] if self.local_rotations.ndim else 0
        if self.local_rotations.shape[1:] != (self.skeleton.num_joints, 3, 3):
            raise MotionError(
                name,
                f"local rotations have shape {self.local_rotations.shape}, expected (T, "
                f"{self.skeleton.num_joints}, 3, 3)",
            )
        if self.root_translation.shape != (t, 3):
            raise MotionError(
                name, f"root translation has shape {self.root_translation.shape}, expected ({t}, 3)"
            )
        if t == 0:
            raise MotionError(name, "the motion has no frames")
        if not (np.isfinite(self.local_rotations).all() and np.isfinite(self.root_translation).all()):
            bad = ~(
                np.isfinite(self.local_rotations).reshape(t, -1).all(1)
                & np.isfinite(self.root_translation).all(1)
            )
            raise MotionError(
                name, f"non-finite values in {int(bad.sum())} frame(s), first at frame {int(np.argmax(bad))}"
            )
        if (
            isinstance(self.fps, bool)
            or not isinstance(self.fps, (int, float, np.number))
            or not MIN_FPS <= self.fps <= MAX_FPS
        ):
            raise MotionError(
                name,
                f"invalid frame rate {self.fps!r}: motions run at {MIN_FPS:g} to {MAX_FPS:g} frames a second",
            )
        reach = float(np.abs(self.root_translation).max())
        if reach > MAX_TRANSLATION_M:
            raise MotionError(
                name,
                f"the pelvis goes {reach:.3g} m from the origin, beyond the {MAX_TRANSLATION_M:g} m a "
                "motion may (float32 vertices lose centimetres there): move the clip nearer the origin",
            )

    @property
    def num_frames(self) -> int:
        return int(self.local_rotations.shape[0])

    @property
    def duration_s(self) -> float:
        return self.num_frames / self.fps

    @cached_property
    def _fk(self) -> tuple[np.ndarray, np.ndarray]:
        from .. import native  # the C form where compiled: a streamed pose's FK is per frame

        lib = native.load_kernel()
        if lib is not None:
            return native.forward_kinematics(
                lib,
                self.local_rotations,
                self.root_translation,
                offsets=self.skeleton.offsets,
                parents=self.skeleton.parents,
            )
        g_rot, g_pos = forward_kinematics(
            self.local_rotations.astype(np.float64),
            self.root_translation.astype(np.float64),
            self.skeleton.offsets.astype(np.float64),
            parents=self.skeleton.parents,
        )
        return g_rot, g_pos

    @property
    def global_rotations(self) -> np.ndarray:
        """(T, 22, 3, 3) world rotations (float64)."""
        return self._fk[0]

    @property
    def joint_positions(self) -> np.ndarray:
        """(T, 22, 3) world joint positions in metres (float64)."""
        return self._fk[1]

    def sole_heights(self) -> np.ndarray:
        """(T, 6) heights of the feet's sole points above the ground plane y = 0."""
        return sole_heights(*self._fk)

    def sole_points(self) -> np.ndarray:
        """(T, 6, 3) world positions of the feet's sole points (heel, ball, toe tip per foot)."""
        return sole_points(*self._fk)

    def lowest_foot_height(self) -> np.ndarray:
        """(T,) height of the lowest sole point per frame."""
        return self.sole_heights().min(axis=1)

    @classmethod
    def concatenate(cls, parts: list["Motion"]) -> "Motion":
        """The frames of ``parts`` one after another (fps, source and skeleton of the first).
        Forward kinematics is per frame, so where every part has already computed it the result
        reuses it instead of computing it again (a stream pairs each new pose with the last)."""
        first = parts[0]
        out = cls(
            np.concatenate([p.local_rotations for p in parts]),
            np.concatenate([p.root_translation for p in parts]),
            first.fps,
            first.source,
            first.source_skeleton,
            first.source_height_m,
            first.skeleton,
            check_rotations=False,
        )
        if all("_fk" in p.__dict__ for p in parts):
            out.__dict__["_fk"] = tuple(np.concatenate([p._fk[i] for p in parts]) for i in range(2))
        return out

    def on_skeletons(self, offsets: np.ndarray, root_scale: np.ndarray) -> "Motion":
        """This motion with each frame played by its own skeleton, ``offsets`` (T, 22, 3), and its
        root's position scaled by ``root_scale`` (T,): a crowd's characters of different bodies, one
        character a frame, each as :func:`~hrr_garment.body.retarget.motion_on_body` plays it. The
        forward kinematics use each frame's offsets; ``skeleton`` stays this motion's own."""
        root = self.root_translation * np.asarray(root_scale, np.float64)[:, None]
        out = Motion(
            self.local_rotations,
            root,
            self.fps,
            self.source,
            self.source_skeleton,
            self.source_height_m,
            self.skeleton,
            check_rotations=False,
        )
        out.__dict__["_fk"] = forward_kinematics(
            self.local_rotations.astype(np.float64),
            root,
            np.asarray(offsets, np.float64),
            parents=self.skeleton.parents,
        )
        return out

    def mirrored(self) -> "Motion":
        """The motion reflected left-right (x -> -x): left and right joints swap, rotations are
        conjugated by the reflection. The canonical skeleton is symmetric, so its joints land on
        the reflected joints of this motion exactly."""
        flip = np.diag([-1.0, 1.0, 1.0]).astype(np.float32)
        local = flip @ self.local_rotations[:, list(MIRROR_JOINTS)] @ flip
        return Motion(
            local,
            self.root_translation * np.array([-1.0, 1.0, 1.0]),
            self.fps,
            f"{self.source} (mirrored)",
            self.source_skeleton,
            self.source_height_m,
            self.skeleton,
            check_rotations=False,
        )

    def slice(self, start: int, stop: int) -> "Motion":
        return Motion(
            self.local_rotations[start:stop],
            self.root_translation[start:stop],
            self.fps,
            self.source,
            self.source_skeleton,
            self.source_height_m,
            self.skeleton,
            check_rotations=False,
        )

    def summary(self) -> dict:
        pos = self.joint_positions
        root = pos[:, JOINT_INDEX["pelvis"]]
        travel = float(np.linalg.norm(np.diff(root[:, [0, 2]], axis=0), axis=1).sum())
        return {
            "source": self.source,
            "source_skeleton": self.source_skeleton,
            "frames": self.num_frames,
            "fps": float(self.fps),
            "duration_s": round(self.duration_s, 4),
            "height_m": round(float(self.source_height_m), 4),
            "root_path_length_m": round(travel, 4),
            "root_displacement_m": round(float(np.linalg.norm(root[-1, [0, 2]] - root[0, [0, 2]])), 4),
            "mean_lowest_foot_height_m": round(float(self.lowest_foot_height().mean()), 4),
        }
