"""``out.h5``: an animated garment as hrr-animate writes it (docs/inference.md). The file format lives in
``data`` (with the dataset's) because inference writes it and export, eval and the previews read it.

    /faces                  (F, 3) int32
    /vertices               (T, V, 3) float32, one frame per chunk, gzip + shuffle
    /body/joints            (T, 22, 3) float32
    /body/capsules          (T, C, 2, 3) float32, the collision capsules' end points a, b
    /body/radii             (C,) float32, their radii
    /body/rotations         (T, 22, 4) float32, the skeleton's local joint rotations, quaternions (x, y, z, w)
    /body/root_translation  (T, 3) float32, the pelvis's position
    /body/offsets           (22, 3) float32, the body's skeleton: each joint's offset from its parent
    /diagnostics/retrieved  (T,) uint8, 1 = the frame's window was retrieved from the database as simulated
    /diagnostics/entropy    (T,) float32, motion-code entropy (nats)
    /diagnostics/match      (T, 2) int32, the database window (sequence, start frame) that gave or lent
                            to the frame (retrieval; the residual and detail modes' match), or -1
    attributes: fps, units ("m"), up_axis ("Y"), garment, source_motion (the motion file),
                body_name (the name of the body animated), body_record (that body as body.json holds
                it, JSON), format_version, model_hash, and the run's
                settings: mode (the inference mode), gate,
                tau, causal, collision, detail_base and detail_strength (detail mode)

Written to a temporary file and renamed, so a failed run leaves no half file.

Versions and the upgrade of older files: :mod:`.animation_versions`; the checks on reading:
:mod:`.animation_checks`.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import h5py
import numpy as np

from ..errors import InputError
from ..garment.material import Material, recorded_material
from ..input_files import input_file
from ..io_utils import atomic_h5
from ..motion.motion import MAX_TRANSLATION_M
from .animation_checks import check_arrays, checked_fps, checked_skeleton
from .animation_versions import (
    FORMAT_VERSION,
    OLD_NAMES,
    file_version,
    upgrade_from_version_2,
    upgrade_from_version_4,
)

SKELETON = (
    "body/rotations",
    "body/root_translation",
    "body/offsets",
)  # version 4: the motion as a skeleton's
MAX_REACH_M = (
    1.5  # metres from the nearest body joint a garment vertex may be (a long dress's hem: under 0.6)
)
PER_FRAME = ("body/joints", "diagnostics/retrieved", "diagnostics/entropy", "diagnostics/match")


@dataclass(frozen=True)
class AnimationFile:
    """The contents of an out.h5, checked: finite vertices, faces in range, per-frame arrays of T rows."""

    path: Path
    vertices: np.ndarray  # (T, V, 3) float32, world, metres, Y up
    faces: np.ndarray  # (F, 3) int32
    joints: np.ndarray  # (T, 22, 3)
    retrieved: np.ndarray  # (T,) uint8
    entropy: np.ndarray  # (T,)
    match: np.ndarray  # (T, 2)
    capsules: np.ndarray | None  # (T, C, 2, 3) or None in version-1 files
    radii: np.ndarray | None  # (C,)
    attrs: dict
    rotations: np.ndarray | None = None  # (T, 22, 4) local quaternions (x, y, z, w); None before version 4
    root_translation: np.ndarray | None = None  # (T, 3)
    offsets: np.ndarray | None = None  # (22, 3)

    @property
    def fps(self) -> float:
        return float(self.attrs["fps"])

    @property
    def num_frames(self) -> int:
        return int(self.vertices.shape[0])

    @cached_property
    def material(self) -> Material | None:
        """The cloth the garment was animated in, where the file records one (written by a model that
        records its cloths); None otherwise."""
        return recorded_material(self.attrs.get("material"), str(self.path))

    @cached_property
    def _visible_body(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The body's own mesh posed by the clip, (T, V, 3) and its faces, where the file records a
        body with a parametric shape and the skeleton's motion (and the ``bodies`` extra is
        installed); None otherwise."""
        from ..body.body_file import body_from_dict
        from ..body.skinned_body import visible_body
        from ..motion.motion import Motion
        from ..motion.rotations import quat_to_matrix
        from ..motion.skeleton import Skeleton

        text = self.attrs.get("body_record")
        if not text or self.rotations is None:
            return None
        try:
            record = json.loads(text)
        except (TypeError, ValueError) as exc:
            raise InputError(self.path, f"the body record attribute is not JSON ({exc})") from None
        mesh = visible_body(body_from_dict(record, self.path))
        if mesh is None:
            return None
        played = Motion(
            quat_to_matrix(self.rotations[..., [3, 0, 1, 2]].astype(np.float64)),
            self.root_translation,
            self.fps,
            skeleton=Skeleton(offsets=np.asarray(self.offsets, np.float32)),
        )
        return mesh.pose(played.global_rotations, played.joint_positions), mesh.faces

    def body_mesh(self, t: int, segments: int = 12, rings: int = 6) -> tuple[np.ndarray, np.ndarray]:
        """(vertices, faces) of the body at frame ``t``: its own mesh where it has one
        (:attr:`_visible_body`), else its capsules; raises when the file has no body."""
        from ..body.capsules import body_mesh

        if self._visible_body is not None:
            return self._visible_body[0][t], self._visible_body[1]
        if self.capsules is None:
            raise InputError(
                self.path,
                "this file has no body capsules (written by an older hrr-animate); "
                "re-run hrr-animate to include the body",
            )
        caps = self.capsules[t].astype(np.float64)
        return body_mesh(
            caps[:, 0], caps[:, 1], self.radii.astype(np.float64), segments=segments, rings=rings
        )


@dataclass(frozen=True)
class AnimationArrays:
    """The arrays an out.h5 holds (shapes in the module docstring)."""

    vertices: np.ndarray
    faces: np.ndarray
    joints: np.ndarray
    retrieved: np.ndarray
    entropy: np.ndarray
    match: np.ndarray
    capsules: np.ndarray | None = None
    radii: np.ndarray | None = None
    rotations: np.ndarray | None = None  # (T, 22, 4) (x, y, z, w)
    root_translation: np.ndarray | None = None
    offsets: np.ndarray | None = None


def write_animation_h5(path: str | Path, arrays: AnimationArrays, attrs: dict) -> Path:
    """Write an out.h5 (the layout in the module docstring) atomically; returns its path."""
    path = Path(path)
    a = arrays
    vertices, faces, joints, capsules, radii = a.vertices, a.faces, a.joints, a.capsules, a.radii
    t, v = vertices.shape[:2]
    with atomic_h5(path) as f:
        f.create_dataset("faces", data=np.asarray(faces, np.int32))
        f.create_dataset(
            "vertices",
            data=np.asarray(vertices, np.float32),
            chunks=(1, v, 3),
            compression="gzip",
            compression_opts=4,
            shuffle=True,
        )
        f.create_dataset("body/joints", data=np.asarray(joints, np.float32))
        if capsules is not None:
            f.create_dataset("body/capsules", data=np.asarray(capsules, np.float32))
            f.create_dataset("body/radii", data=np.asarray(radii, np.float32))
        if a.rotations is not None:
            for key, value in zip(SKELETON, (a.rotations, a.root_translation, a.offsets)):
                f.create_dataset(key, data=np.asarray(value, np.float32))
        f.create_dataset("diagnostics/retrieved", data=np.asarray(a.retrieved, np.uint8))
        f.create_dataset("diagnostics/entropy", data=np.asarray(a.entropy, np.float32))
        f.create_dataset("diagnostics/match", data=np.asarray(a.match, np.int32).reshape(t, 2))
        f.attrs.update({"fps": 30.0, "units": "m", "up_axis": "Y", "format_version": FORMAT_VERSION})
        f.attrs.update({k: v for k, v in attrs.items() if v is not None})
    return path


def read_animation_h5(path: str | Path) -> AnimationFile:
    """Read and check an out.h5; problems raise :class:`InputError` naming the file."""
    path = Path(path)
    input_file(path, "an animation file")
    try:
        f = h5py.File(path, "r")
    except OSError as exc:
        raise InputError(path, f"not an HDF5 file ({exc})") from None
    try:
        with f:
            attrs = dict(f.attrs)
            version = file_version(path, attrs)
            names = {**{k: k for k in PER_FRAME}, **(OLD_NAMES if version < 3 else {})}
            missing = [k for k in ("faces", "vertices") if k not in f] + [
                names[k] for k in PER_FRAME if names[k] not in f
            ]
            if missing:
                raise InputError(path, f"not an hrr-animate file: missing {', '.join(missing)}")
            vertices = f["vertices"][()]
            faces = f["faces"][()]
            per_frame = {k: f[names[k]][()] for k in PER_FRAME}
            capsules = f["body/capsules"][()] if "body/capsules" in f else None
            radii = f["body/radii"][()] if "body/radii" in f else None
            skeleton = {k: f[k][()] for k in SKELETON if k in f}
    except (
        OSError,
        RuntimeError,
        ValueError,
        TypeError,
        KeyError,
    ) as exc:  # damaged chunks, headers, attributes
        raise InputError(
            path, f"damaged file, cannot be read ({type(exc).__name__}: {str(exc)[:200]})"
        ) from None
    attrs["fps"] = checked_fps(path, attrs)
    if version < 3:
        per_frame, attrs = upgrade_from_version_2(per_frame, attrs)
    if version < 5:
        attrs = upgrade_from_version_4(attrs)
    check_arrays(path, vertices, faces, per_frame=per_frame, capsules=capsules, radii=radii)
    _check_on_body(path, vertices, per_frame["body/joints"])
    skeleton = checked_skeleton(path, skeleton, vertices.shape[0])
    return AnimationFile(
        path=path,
        vertices=vertices.astype(np.float32),
        faces=faces.astype(np.int32),
        joints=per_frame["body/joints"],
        retrieved=per_frame["diagnostics/retrieved"].astype(np.uint8),
        entropy=per_frame["diagnostics/entropy"],
        match=per_frame["diagnostics/match"],
        capsules=capsules,
        radii=radii,
        attrs=attrs,
        **skeleton,
    )


def farthest_from_body(vertices: np.ndarray, joints: np.ndarray) -> tuple[float, int]:
    """How far (m) the garment vertex farthest from its nearest body joint is, over (T, V, 3)
    vertices and (T, J, 3) joints, and the first frame where it is more than ``MAX_REACH_M`` (-1:
    none); a block of frames at a time."""
    worst, first = 0.0, -1
    for t in range(0, len(vertices), 256):
        v, j = vertices[t : t + 256].astype(np.float64), joints[t : t + 256].astype(np.float64)
        reach = np.sqrt(((v[:, :, None] - j[:, None]) ** 2).sum(-1).min(-1)).max(1)
        worst = max(worst, float(reach.max()))
        if first < 0 and (reach > MAX_REACH_M).any():
            first = t + int(np.argmax(reach > MAX_REACH_M))
    return worst, first


def _check_on_body(path: Path, vertices: np.ndarray, joints: np.ndarray) -> None:
    """What hrr-animate refuses to write is refused on reading too: exporting it would hand on an
    absurd result (a vertex at 1e30, a body beyond any scene)."""
    far = float(np.abs(joints).max())
    if far > MAX_TRANSLATION_M:
        raise InputError(
            path,
            f"/body/joints go {far:.3g} m from the origin, beyond the {MAX_TRANSLATION_M:g} m a motion may",
        )
    reach, frame = farthest_from_body(vertices, joints)
    if frame >= 0:
        raise InputError(
            path,
            f"a garment vertex is {reach:.3g} m from the body at frame {frame} (more than "
            f"{MAX_REACH_M:g} m): not cloth on a body (a damaged or edited file?)",
        )
