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
                body (the name of the body animated), body_record (that body as body.json holds it,
                JSON), format_version, model_hash, and the run's
                settings: mode (the inference mode), gate,
                tau, causal, collision, detail_base and detail_strength (detail mode)

Written to a temporary file and renamed, so a failed run leaves no half file.

Versions (``format_version``; :func:`read_animation_h5` upgrades older files as it reads them):
1 had no body capsules (still read; only what needs the body refuses such a file); 2 added them;
3 renamed ``diagnostics/mode`` to ``diagnostics/retrieved`` (the inference mode is the ``mode``
attribute) and ``diagnostics/source`` to ``diagnostics/match``, and ``retrieved`` no longer marks
the residual and detail modes' frames, whose windows are the regression's with a match's detail;
4 added the skeleton's motion (``body/rotations``, ``body/root_translation``, ``body/offsets``: what
a character's skinned mesh is posed by in an export; older files export without it).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import h5py
import numpy as np

from ..errors import InputError
from ..io_utils import atomic_h5
from ..motion.motion import MAX_TRANSLATION_M

FORMAT_VERSION = 4
SKELETON = (
    "body/rotations",
    "body/root_translation",
    "body/offsets",
)  # version 4: the motion as a skeleton's
MAX_REACH_M = (
    1.5  # metres from the nearest body joint a garment vertex may be (a long dress's hem: under 0.6)
)
PER_FRAME = ("body/joints", "diagnostics/retrieved", "diagnostics/entropy", "diagnostics/match")


def _fps(path: Path, attrs: dict) -> float:
    """The file's frame rate attribute: one finite number in [1, 1000]."""
    if "fps" not in attrs:
        raise InputError(path, "missing the 'fps' attribute")
    value = np.asarray(attrs["fps"])
    if value.size != 1 or value.dtype.kind not in "iuf" or not 1 <= float(value.item()) <= 1000:
        raise InputError(
            path, f"the 'fps' attribute must be a frame rate in [1, 1000], got {str(attrs['fps'])[:40]!r}"
        )
    return float(value.item())


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
    def _visible_body(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The body's own mesh posed by the clip, (T, V, 3) and its faces, where the file records a
        body with a parametric shape and the skeleton's motion (and the ``bodies`` extra is
        installed); None otherwise."""
        from ..body.body_file import body_from_dict
        from ..body.mesh_collider import visible_body
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
    if not path.is_file():
        raise InputError(path, "no such file")
    try:
        f = h5py.File(path, "r")
    except OSError as exc:
        raise InputError(path, f"not an HDF5 file ({exc})") from None
    try:
        with f:
            attrs = dict(f.attrs)
            version = _version(path, attrs)
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
    attrs["fps"] = _fps(path, attrs)
    if version < 3:
        per_frame, attrs = _from_version_2(per_frame, attrs)
    for key, arr in (("vertices", vertices), ("faces", faces), *per_frame.items()):
        if not isinstance(arr, np.ndarray) or arr.dtype.kind not in "biuf":
            raise InputError(path, f"/{key} must hold numbers, got {getattr(arr, 'dtype', type(arr))}")
    if vertices.ndim != 3 or vertices.shape[2] != 3 or vertices.shape[0] < 1:
        raise InputError(path, f"/vertices must be (T, V, 3) with T >= 1, got {vertices.shape}")
    if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) == 0:
        raise InputError(path, f"/faces must be (F, 3), got {faces.shape}")
    if faces.min() < 0 or faces.max() >= vertices.shape[1]:
        raise InputError(path, f"/faces index vertices outside 0..{vertices.shape[1] - 1}")
    for key, arr in (
        ("vertices", vertices),
        ("body/joints", per_frame["body/joints"]),
        ("body/capsules", capsules),
        ("body/radii", radii),
    ):
        if arr is not None and arr.dtype.kind == "f" and not np.isfinite(arr).all():
            frames = np.flatnonzero(~np.isfinite(arr.reshape(len(arr), -1)).all(1))
            raise InputError(
                path, f"/{key} has non-finite values at frame {frames[0]} ({len(frames)} frames)"
            )
    t = vertices.shape[0]
    for key, arr in per_frame.items():
        if arr.ndim == 0 or arr.shape[0] != t:
            raise InputError(path, f"/{key} has {arr.shape[:1]} rows, /vertices has {t} frames")
    if per_frame["body/joints"].shape[1:] != (22, 3):
        raise InputError(path, f"/body/joints must be (T, 22, 3), got {per_frame['body/joints'].shape}")
    if capsules is not None and (
        capsules.shape[:1] != (t,)
        or capsules.shape[2:] != (2, 3)
        or radii is None
        or radii.shape != capsules.shape[1:2]
    ):
        raise InputError(
            path,
            f"/body/capsules {capsules.shape} and /body/radii "
            f"{None if radii is None else radii.shape} do not match (T, C, 2, 3) and (C,)",
        )
    _check_on_body(path, vertices, per_frame["body/joints"])
    skeleton = _checked_skeleton(path, skeleton, t)
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


def _checked_skeleton(path: Path, found: dict, frames: int) -> dict:
    """The skeleton's motion (version 4) as AnimationFile's fields, each checked; none where absent."""
    if not found:
        return {}
    shapes = {
        "body/rotations": (frames, 22, 4),
        "body/root_translation": (frames, 3),
        "body/offsets": (22, 3),
    }
    for key, shape in shapes.items():
        arr = found.get(key)
        if arr is None or arr.shape != shape or arr.dtype.kind != "f" or not np.isfinite(arr).all():
            raise InputError(
                path,
                f"/{key} must be finite numbers of shape {shape}, got "
                f"{None if arr is None else (arr.shape, str(arr.dtype))}",
            )
    return {
        "rotations": found["body/rotations"],
        "root_translation": found["body/root_translation"],
        "offsets": found["body/offsets"],
    }


#: version 1 and 2 names of the datasets version 3 renamed
OLD_NAMES = {"diagnostics/retrieved": "diagnostics/mode", "diagnostics/match": "diagnostics/source"}


def _version(path: Path, attrs: dict) -> int:
    """The file's format version (1 where it has none): one this hrr_garment reads."""
    version = attrs.get("format_version", 1)
    if isinstance(version, (bool, np.bool_)) or not isinstance(version, (int, np.integer)) or version < 1:
        raise InputError(path, f"format_version must be a positive integer, got {version!r}")
    if version > FORMAT_VERSION:
        raise InputError(
            path,
            f"format version {version} is newer than this hrr_garment reads ({FORMAT_VERSION}); "
            "upgrade hrr_garment",
        )
    return int(version)


def _from_version_2(per_frame: dict, attrs: dict) -> tuple[dict, dict]:
    """Versions 1-2 -> 3: ``retrieved`` marked every frame of the residual and detail modes (their
    database match), which version 3 records in ``match`` only."""
    if str(attrs.get("mode", "")) in ("residual", "detail"):
        per_frame = {**per_frame, "diagnostics/retrieved": np.zeros_like(per_frame["diagnostics/retrieved"])}
    return per_frame, {**attrs, "format_version": FORMAT_VERSION}
