"""The bodies of a dataset: each body's record and the garment on it in its rest pose.

A dataset simulated on bodies other than the mannequin keeps each of them (:mod:`.dataset`,
``/bodies/<name>``), and each sequence names the body it was simulated on. The garment on a body
has the template's topology (the same vertices, faces and groups) and that body's rest shape, so a
sequence's strain, its penetration and a model's predictions are measured against its own body.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, replace

import numpy as np

from ..body.body_file import BodyRecord, body_from_dict, body_to_dict
from ..body.capsules import DEFAULT_BODY, BodyModel
from ..garment.mesh import GarmentMesh, mirror_map
from ..garment.transfer import TransferReport, transfer_garment
from ..io_utils import strict_json
from ..motion.skeleton import CANONICAL, MIRROR_JOINTS, REST_PELVIS_HEIGHT

MANNEQUIN = "mannequin"  # the name of the default body (sequences that name no body stand on it)
MANNEQUIN_STATURE_M = 1.70


def mannequin_record() -> BodyRecord:
    """The mannequin as a body record (the canonical skeleton and the default capsules)."""
    return BodyRecord(CANONICAL, DEFAULT_BODY, pelvis_height=REST_PELVIS_HEIGHT, stature=MANNEQUIN_STATURE_M)


@dataclass(frozen=True)
class DressedBody:
    """A body and the garment on it, both in their rest poses."""

    name: str
    record: BodyRecord
    garment: GarmentMesh  # the template's topology, this body's rest shape

    @property
    def body(self) -> BodyModel:
        return self.record.body

    @property
    def is_mannequin(self) -> bool:
        return self.record.body.is_mannequin_frame and self.record.body.capsules == DEFAULT_BODY.capsules

    def offset(self, template: GarmentMesh) -> np.ndarray:
        """(V, 3) float32 where this body's garment at rest stands in the body frame
        (:mod:`hrr_garment.motion.frame`) less where the template stands on the mannequin: zero on
        the mannequin. Models learn each frame less its body's offset (the garment's motion
        relative to its own body at rest) and add the offset of the body they animate; the body
        frame's origin sits the canonical rest pelvis height under the pelvis, so a taller body's
        garment stands higher in it."""
        lift = np.array([0.0, self.record.pelvis_height - REST_PELVIS_HEIGHT, 0.0], np.float32)
        return (self.garment.vertices - lift - template.vertices).astype(np.float32)

    def key(self) -> str:
        """A short content hash of the body (skeleton, capsules, heights) and the garment's rest
        shape: what a simulated sequence on it depends on (its fit report and shape do not)."""
        data = {k: v for k, v in body_to_dict(self.record).items() if k not in ("fit", "shape")}
        h = hashlib.sha1(strict_json(data).encode())
        for arr in (self.garment.vertices, self.garment.faces, self.garment.attached):
            h.update(np.ascontiguousarray(arr).tobytes())
        return h.hexdigest()[:16]


@dataclass(frozen=True)
class _Halves:
    """A body beside its mirror image (x -> -x): the skeleton's offsets and each capsule's ends and
    radius, next to those of its left-right partner reflected (a capsule across the midline is its
    own partner, its ends swapped where that matches)."""

    offsets: np.ndarray  # (22, 3)
    mirrored_offsets: np.ndarray
    ends: np.ndarray  # (C, 2, 3)
    mirrored_ends: np.ndarray
    radii: np.ndarray  # (C,)
    mirrored_radii: np.ndarray

    def gap(self) -> float:
        """The largest left-right difference, metres."""
        return float(
            max(
                np.abs(self.mirrored_offsets - self.offsets).max(),
                np.abs(self.mirrored_ends - self.ends).max(),
                np.abs(self.mirrored_radii - self.radii).max(),
            )
        )


def _halves(body: BodyModel) -> _Halves | None:
    """``body`` beside its mirror image, or None where a capsule has no left-right partner."""
    flip = np.array([-1.0, 1.0, 1.0])
    by_name = {c.name: c for c in body.capsules}
    if any(_mirror_name(c.name) not in by_name for c in body.capsules):
        return None
    ends, mirrored = [], []
    for c in body.capsules:
        other = by_name[_mirror_name(c.name)]
        mine, theirs = np.array([c.a, c.b]), np.array([other.a, other.b]) * flip
        if other is c:  # a capsule across the midline mirrors onto itself with its ends swapped
            theirs = (
                theirs[::-1] if np.abs(theirs[::-1] - mine).max() < np.abs(theirs - mine).max() else theirs
            )
        ends.append(mine)
        mirrored.append(theirs)
    offsets = np.asarray(body.skeleton.offsets, np.float64)
    radii = body.radii.astype(np.float64)
    index = {c.name: i for i, c in enumerate(body.capsules)}
    partner = [index[_mirror_name(c.name)] for c in body.capsules]
    return _Halves(
        offsets,
        offsets[list(MIRROR_JOINTS)] * flip,
        np.array(ends),
        np.array(mirrored),
        radii,
        radii[partner],
    )


def is_symmetric(body: BodyModel, tolerance: float = 1e-3) -> bool:
    """Whether ``body`` is its own mirror image (x -> -x) within ``tolerance`` metres: left and right
    bones of one length, capsules in mirrored places with equal radii. A sequence on it can be
    mirrored exactly; on an asymmetric body the mirror would stand on another body."""
    halves = _halves(body)
    return halves is not None and halves.gap() <= tolerance


# a body whose left and right differ by less is made exactly symmetric: anny's bodies are, but their
# fitted capsules differ side to side by up to 1 cm in a bone and 2.5 cm in a shoulder's radius
# (the vertices between shoulder and upper arm split differently on each side)
NEARLY_SYMMETRIC_M = 0.03


def symmetrized(body: BodyModel, tolerance: float = NEARLY_SYMMETRIC_M) -> BodyModel:
    """``body`` with left and right averaged, where they differ by less than ``tolerance`` (made
    exact, its sequences can be mirrored); else ``body`` as it is."""
    from dataclasses import replace

    from ..motion.skeleton import Skeleton

    halves = _halves(body)
    if halves is None or halves.gap() > tolerance:
        return body
    ends = 0.5 * (halves.ends + halves.mirrored_ends)
    radii = 0.5 * (halves.radii + halves.mirrored_radii)
    capsules = tuple(
        replace(c, a=tuple(float(v) for v in e[0]), b=tuple(float(v) for v in e[1]), radius=float(r))
        for c, e, r in zip(body.capsules, ends, radii)
    )
    skeleton = Skeleton(offsets=(0.5 * (halves.offsets + halves.mirrored_offsets)).astype(np.float32))
    return replace(body, capsules=capsules, skeleton=skeleton)


def dress(
    name: str, record: BodyRecord, garment: GarmentMesh, *, made_for: BodyModel
) -> tuple[DressedBody, TransferReport]:
    """The body (left and right made exactly alike where they nearly are: its sequences can then be
    mirrored) and ``garment`` (modelled on ``made_for``) carried onto it."""
    body = symmetrized(record.body)
    record = replace(record, body=body, skeleton=body.skeleton)
    on_body, report = transfer_garment(garment, made_for=made_for, body=body)
    perm = mirror_map(garment.vertices) if is_symmetric(made_for) else None
    if perm is not None and is_symmetric(body):  # exactly symmetric, as the template was
        flip = np.array([-1.0, 1.0, 1.0], np.float32)
        on_body = replace(on_body, vertices=0.5 * (on_body.vertices + on_body.vertices[perm] * flip))
    return DressedBody(name, record, on_body), report


def _mirror_name(name: str) -> str:
    if name.startswith("l_"):
        return "r_" + name[2:]
    if name.startswith("r_"):
        return "l_" + name[2:]
    return name


def write_bodies(f, template: GarmentMesh, used: set[str], bodies: dict[str, DressedBody]) -> None:
    """Write the bodies named in ``used`` under ``/bodies`` of the open HDF5 file ``f``: each one's
    body.json content and the garment's rest shape on it (the template's topology)."""
    missing = sorted(used - set(bodies))
    if missing:
        raise ValueError(f"sequences name bodies that were not given: {missing}")
    if not used:
        return
    group = f.create_group("bodies")
    for name in sorted(used):
        rest = bodies[name].garment.vertices
        if rest.shape != template.vertices.shape or not np.array_equal(
            bodies[name].garment.faces, template.faces
        ):
            raise ValueError(f"the garment on body {name!r} does not have the template's topology")
        b = group.create_group(name)
        b.create_dataset("rest", data=rest.astype(np.float32))
        b.attrs["body"] = json.dumps(body_to_dict(bodies[name].record))


def read_bodies(f, template: GarmentMesh, source: str) -> dict[str, DressedBody]:
    """The mannequin (with ``template``) and every body under ``/bodies`` of the open HDF5 file
    ``f`` (with the garment on it); a damaged entry raises ValueError (``source`` names the file
    for body.json's own checks)."""
    bodies = {MANNEQUIN: DressedBody(MANNEQUIN, mannequin_record(), template)}
    for name, b in f.get("bodies", {}).items():
        try:
            data = json.loads(b.attrs.get("body", "{}"))
        except (TypeError, ValueError) as exc:
            raise ValueError(f"body {name!r}: attribute 'body' is not valid JSON ({exc})") from None
        if not isinstance(data, dict):
            raise ValueError(
                f"body {name!r}: attribute 'body' should hold a dict, not a {type(data).__name__}"
            )
        record = body_from_dict(data, f"{source} (body {name!r})")
        rest = b["rest"][()]
        if rest.shape != template.vertices.shape or not np.isfinite(rest).all():
            raise ValueError(
                f"body {name!r}: the garment's rest shape {rest.shape} is not finite "
                f"or not the template's {template.vertices.shape}"
            )
        bodies[name] = DressedBody(
            name,
            record,
            GarmentMesh(
                template.name,
                rest,
                template.faces,
                groups=template.groups,
                attached_groups=template.attached_groups,
            ),
        )
    return bodies
