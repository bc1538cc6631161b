"""The garment dataset file (HDF5): one template, many simulated sequences, fixed splits.

Layout (format_version 3; documented in docs/dataset.md)::

    /                      attrs: format_version, fps, garment, units="m", up_axis="y", generator, info (JSON)
    /template/vertices     (V, 3) float32, rest pose
    /template/faces        (F, 3) int32
    /template/attached     (A,) int32
    /template/groups/<g>   (n,) int32, named vertex groups (attrs: attached_groups on /template)
    /sequences/<name>/garment          (T, V, 3) float32, world space
    /sequences/<name>/joints           (T, 22, 3) float32, world joint positions
    /sequences/<name>/local_rotations  (T, 22, 3, 3) float32
    /sequences/<name>/root_translation (T, 3) float64
                      attrs: source, info (JSON: kind, seed, stats...), body_name (a name under
                      /bodies; absent: the mannequin)
    /bodies/<name>/rest                (V, 3) float32, the garment on this body in its rest pose
                  attrs: body (JSON: body.json's content, hrr_garment.body.body_file)
    /splits/{train,val,test}           names of sequences (variable-length UTF-8 strings)

A sequence on a body has that body's motion: the rotations drive the body's own skeleton and the
root translation is already scaled to its legs (:func:`hrr_garment.body.retarget.motion_on_body`),
so ``sequence(name).motion`` is what moved the cloth. Version 1 files (every sequence on the
mannequin, no /bodies) read as before, and so do version 2's, whose sequences name their body in
the attribute ``body`` (version 3 calls it ``body_name``, leaving ``body`` to /bodies' records).
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import h5py
import numpy as np

from .._version import __version__
from ..body.mannequin import MANNEQUIN
from ..errors import InputError, MotionError
from ..garment.dressing import DressedBody
from ..garment.fabrics import FABRICS
from ..garment.material import Material, material_from
from ..garment.mesh import GarmentError, GarmentMesh, check_garment
from ..motion.motion import FPS, Motion
from .dataset_bodies import read_bodies, write_bodies

FORMAT_VERSION = 3
READABLE_VERSIONS = (1, 2, 3)
#: a sequence's attribute naming its body, by format version (3 renamed it)
BODY_NAME_ATTR = {1: "body", 2: "body", 3: "body_name"}
SPLITS = ("train", "val", "test")


class DatasetError(InputError):
    """A dataset file that is missing, of another format, or inconsistent."""


@dataclass
class SequenceRecord:
    """One sequence: garment vertices (T, V, 3) world space and the motion that drove them."""

    name: str
    garment: np.ndarray
    motion: Motion
    info: dict = field(default_factory=dict)
    body_name: str = MANNEQUIN  # the name of the body it was simulated on (GarmentDataset.bodies)
    dressed: DressedBody | None = None  # that body and the garment at rest on it, as read from a dataset
    material: Material | None = None  # the cloth it was simulated in, as read from a dataset


def write_dataset(
    path: str | Path,
    template: GarmentMesh,
    sequences: list[SequenceRecord],
    splits: dict[str, list[str]],
    info: dict | None = None,
    compression: str | None = "gzip",
    bodies: dict[str, DressedBody] | None = None,
) -> Path:
    """Write the whole file atomically (temporary file in the same folder, then rename). Sequences
    on a body other than the mannequin need it in ``bodies`` (name -> the body and the garment on it)."""
    from ..io_utils import atomic_h5

    path = Path(path)
    with atomic_h5(path) as f:
        f.attrs.update(
            format_version=FORMAT_VERSION,
            fps=float(sequences[0].motion.fps if sequences else FPS),
            garment=template.name,
            units="m",
            up_axis="y",
            generator=f"hrr_garment {__version__}",
            info=json.dumps(info or {}),
        )
        t = f.create_group("template")
        t.create_dataset("vertices", data=template.vertices.astype(np.float32))
        t.create_dataset("faces", data=template.faces.astype(np.int32))
        t.create_dataset("attached", data=template.attached.astype(np.int32))
        t.attrs["attached_groups"] = json.dumps(list(template.attached_groups))
        g = t.create_group("groups")
        for name, idx in template.groups.items():
            g.create_dataset(name, data=np.asarray(idx, np.int32))
        seqs = f.create_group("sequences")
        opts = {"compression": compression, "shuffle": True} if compression else {}
        for rec in sequences:
            s = seqs.create_group(rec.name)
            v = rec.garment.astype(np.float32)
            s.create_dataset("garment", data=v, chunks=(1,) + v.shape[1:], **opts)
            s.create_dataset("joints", data=rec.motion.joint_positions.astype(np.float32), **opts)
            s.create_dataset("local_rotations", data=rec.motion.local_rotations.astype(np.float32), **opts)
            s.create_dataset("root_translation", data=rec.motion.root_translation.astype(np.float64))
            s.attrs["source"] = rec.motion.source
            s.attrs["info"] = json.dumps(rec.info)
            if rec.body_name != MANNEQUIN:
                s.attrs[BODY_NAME_ATTR[FORMAT_VERSION]] = rec.body_name
        used = {rec.body_name for rec in sequences} - {MANNEQUIN}
        write_bodies(f, template, used=used, bodies=bodies or {})
        sp = f.create_group("splits")
        str_type = h5py.string_dtype("utf-8")
        for split in SPLITS:
            sp.create_dataset(split, data=np.array(splits.get(split, []), dtype=object), dtype=str_type)
    return path


SEQUENCE_ARRAYS = ("garment", "local_rotations", "root_translation")  # what every sequence must hold
MAX_GARMENT_REACH_M = 3.0  # a simulated dress stays within 0.8 m of the pelvis; 3 m is another unit or frame


class GarmentDataset:
    """Read access to a dataset file; checks the format on open.

    >>> ds = GarmentDataset("hrr_work/datasets/dress-quick.h5")
    >>> ds.splits["train"][:2], ds.template.num_vertices
    >>> rec = ds.sequence(ds.names[0])   # SequenceRecord with garment (T, V, 3) and motion
    """

    def __init__(self, path: str | Path):
        self.path = Path(path)
        if not self.path.is_file():
            raise DatasetError(self.path, "no such dataset file (make one with hrr-simulate or hrr-import)")
        try:
            with h5py.File(self.path, "r") as f:
                self._read_header(f)
        except (OSError, RuntimeError) as exc:  # HDF5's own damage reports ("bad local heap signature")
            raise DatasetError(self.path, f"not a readable HDF5 file ({exc})") from None
        except (KeyError, ValueError, TypeError, IndexError) as exc:  # a header of the wrong shape or type
            raise DatasetError(self.path, f"damaged header ({type(exc).__name__}: {exc})") from None

    def _read_header(self, f: h5py.File) -> None:
        version = f.attrs.get("format_version")
        if version not in READABLE_VERSIONS:
            raise DatasetError(
                self.path,
                f"format_version {version!r}; this hrr_garment reads "
                f"{', '.join(map(str, READABLE_VERSIONS))}",
            )
        for key in ("template/vertices", "template/faces", "template/attached", "sequences", "splits"):
            if key not in f:
                raise DatasetError(self.path, f"missing /{key}")
        self.fps = float(f.attrs["fps"])
        self.garment = str(f.attrs["garment"])
        self.info = _json_attr(self.path, f.attrs, "info", {})
        t = f["template"]
        groups = {k: t["groups"][k][()] for k in t.get("groups", {})}
        attached_groups = tuple(_json_attr(self.path, t.attrs, "attached_groups", []))
        if not attached_groups:
            groups["attached"] = t["attached"][()]
            attached_groups = ("attached",)
        self.template = GarmentMesh(
            self.garment, t["vertices"][()], t["faces"][()], groups=groups, attached_groups=attached_groups
        )
        try:
            check_garment(self.template)
        except GarmentError as exc:
            raise DatasetError(self.path, f"its template garment: {exc.problem}") from None
        self.names = sorted(f["sequences"].keys())
        self.splits = {
            s: [n.decode() if isinstance(n, bytes) else str(n) for n in f["splits"][s][()]]
            for s in SPLITS
            if s in f["splits"]
        }
        missing = sorted({n for names in self.splits.values() for n in names} - set(self.names))
        if missing:
            raise DatasetError(self.path, f"splits name sequences that are not in the file: {missing[:5]}")
        for key in SEQUENCE_ARRAYS:
            lacking = [n for n in self.names if key not in f["sequences"][n]]
            if lacking:
                raise DatasetError(
                    self.path,
                    f"sequence {lacking[0]!r} lacks {key!r}"
                    + (f" (and {len(lacking) - 1} more)" if len(lacking) > 1 else ""),
                )
        for n in self.names:  # shapes from the headers only: cheap, and a bad file fails before any training
            s = f["sequences"][n]
            frames = s["garment"].shape[0]
            shapes = {k: s[k].shape for k in SEQUENCE_ARRAYS}
            if (
                shapes["garment"][1:] != self.template.vertices.shape
                or shapes["local_rotations"][0] != frames
                or shapes["root_translation"] != (frames, 3)
            ):
                raise DatasetError(
                    self.path,
                    f"sequence {n!r}: arrays of mismatched shapes {shapes} "
                    f"for a template of {self.template.num_vertices} vertices",
                )
        self.frames = {n: int(f["sequences"][n]["garment"].shape[0]) for n in self.names}
        key = BODY_NAME_ATTR[version]
        self.body_name_of = {n: str(f["sequences"][n].attrs.get(key, MANNEQUIN)) for n in self.names}
        try:
            self.bodies = read_bodies(f, self.template, str(self.path))
        except ValueError as exc:
            raise DatasetError(self.path, str(exc)) from None
        unknown = sorted({b for b in self.body_name_of.values()} - set(self.bodies))
        if unknown:
            raise DatasetError(self.path, f"sequences name bodies that are not in /bodies: {unknown[:5]}")

    def content_key(self) -> str:
        """A short hash of what the file holds, cheap to take: every sequence's name, shape and
        first and last garment frames. A dataset made again with other frames (another cloth, stops
        held longer, a sequence imported anew) has another; one assembled again from the same parts
        (only its run's timings differ) the same."""
        h = hashlib.sha1()
        with h5py.File(self.path, "r") as f:
            for name in self.names:
                garment = f["sequences"][name]["garment"]
                h.update(name.encode() + np.asarray(garment.shape, np.int64).tobytes())
                h.update(
                    np.ascontiguousarray(garment[0]).tobytes() + np.ascontiguousarray(garment[-1]).tobytes()
                )
        return h.hexdigest()[:16]

    def material_of(self, name: str) -> Material:
        """The cloth sequence ``name`` was simulated in: its own where the build gave each sequence
        one (sim/material_plan.py), else the dataset's (its simulator settings'), else the default
        cloth every dataset had before materials."""
        self._require(name)
        return self._materials[name]

    @cached_property
    def _materials(self) -> dict[str, Material]:
        """Every sequence's cloth (:meth:`material_of`), its info read once, when first asked."""
        with h5py.File(self.path, "r") as f:
            own = {
                n: _json_attr(self.path, f["sequences"][n].attrs, "info", {}, f"sequence {n!r}: ").get(
                    "material"
                )
                for n in self.names
            }
        everyone = self.info.get("sim", {}).get("material")
        return {
            n: material_from(m if m is not None else everyone or FABRICS["default"], f"{self.path}: {n}")
            for n, m in own.items()
        }

    def _require(self, name: str) -> None:
        """A DatasetError unless the file holds sequence ``name``."""
        if name not in self.frames:
            raise DatasetError(
                self.path, f"no sequence {name!r} (has {len(self.names)}: {self.names[:5]}...)"
            )

    def rest(self, name: str) -> np.ndarray:
        """(V, 3) the rest shape of the garment of sequence ``name`` (on its own body)."""
        return self.bodies[self.body_name_of[name]].garment.vertices

    def __len__(self) -> int:
        return len(self.names)

    def sequence(self, name: str) -> SequenceRecord:
        """One sequence, checked: its arrays present, readable, finite and of the template's shape."""
        try:
            with h5py.File(self.path, "r") as f:
                self._require(name)
                s = f["sequences"][name]
                for key in SEQUENCE_ARRAYS:
                    if key not in s:
                        raise DatasetError(self.path, f"sequence {name!r} lacks {key!r}")
                garment = s["garment"][()]
                body = self.bodies[self.body_name_of[name]].body
                motion = Motion(
                    s["local_rotations"][()],
                    s["root_translation"][()],
                    self.fps,
                    source=str(s.attrs.get("source", name)),
                    skeleton=body.skeleton,
                )
                info = _json_attr(self.path, s.attrs, "info", {}, f"sequence {name!r}: ")
        except (OSError, RuntimeError) as exc:  # a damaged chunk ("filter returned failure"), a bad heap
            raise DatasetError(self.path, f"sequence {name!r} cannot be read ({exc})") from None
        except MotionError as exc:  # the motion's own checks (shapes, frames)
            raise DatasetError(self.path, f"sequence {name!r}: {exc.problem}") from None
        if garment.shape[1:] != self.template.vertices.shape or garment.shape[0] != motion.num_frames:
            raise DatasetError(
                self.path,
                f"sequence {name!r}: garment {garment.shape} does not match "
                f"{motion.num_frames} frames x {self.template.num_vertices} vertices",
            )
        for what, values in (
            ("garment vertices", garment),
            ("rotations", motion.local_rotations),
            ("root translations", motion.root_translation),
        ):
            bad = ~np.isfinite(values.reshape(len(values), -1)).all(1)
            if bad.any():
                raise DatasetError(
                    self.path,
                    f"sequence {name!r}: non-finite {what} on {int(bad.sum())} frame(s), "
                    f"first at frame {int(np.argmax(bad))}",
                )
        reach = np.linalg.norm(garment - motion.root_translation[:, None].astype(garment.dtype), axis=-1).max(
            1
        )
        if (reach > MAX_GARMENT_REACH_M).any():
            frame = int(np.argmax(reach > MAX_GARMENT_REACH_M))
            raise DatasetError(
                self.path,
                f"sequence {name!r}: a garment vertex {reach[frame]:.3g} m from the pelvis at frame "
                f"{frame}, beyond {MAX_GARMENT_REACH_M:g} m: the garment is in another unit or place "
                "than the body",
            )
        body_name = self.body_name_of[name]
        return SequenceRecord(
            name,
            garment,
            motion,
            info,
            body_name=body_name,
            dressed=self.bodies[body_name],
            material=self.material_of(name),
        )


def _json_attr(path: Path, attrs, key: str, default, where: str = ""):
    """A JSON-valued HDF5 attribute, or a DatasetError that names it."""
    raw = attrs.get(key)
    if raw is None:
        return default
    try:
        value = json.loads(raw)
    except (TypeError, ValueError) as exc:
        raise DatasetError(path, f"{where}attribute {key!r} is not valid JSON ({exc})") from None
    if not isinstance(value, type(default)):
        raise DatasetError(
            path,
            f"{where}attribute {key!r} should hold a {type(default).__name__}, not a {type(value).__name__}",
        )
    return value
