"""The bodies of a dataset: each body's record and the garment on it in its rest pose.

A dataset simulated on bodies other than the mannequin keeps each of them (:mod:`.dataset`,
``/bodies/<name>``), and each sequence names the body it was simulated on. The garment on a body
has the template's topology (the same vertices, faces and groups) and that body's rest shape, so a
sequence's strain, its penetration and a model's predictions are measured against its own body.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np

from ..body.body_file import BodyRecord, body_to_dict
from ..body.capsules import DEFAULT_BODY, BodyModel
from ..garment.mesh import GarmentMesh
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

    def key(self) -> str:
        """A short content hash of the body (skeleton, capsules, heights) and the garment's rest
        shape: what a simulated sequence on it depends on (its fit report and shape do not)."""
        data = {k: v for k, v in body_to_dict(self.record).items() if k not in ("fit", "shape")}
        h = hashlib.sha1(strict_json(data).encode())
        for arr in (self.garment.vertices, self.garment.faces, self.garment.attached):
            h.update(np.ascontiguousarray(arr).tobytes())
        return h.hexdigest()[:16]


def is_symmetric(body: BodyModel, tolerance: float = 1e-3) -> bool:
    """Whether ``body`` is its own mirror image (x -> -x) within ``tolerance`` metres: left and right
    bones of one length, capsules in mirrored places with equal radii. A sequence on it can be
    mirrored exactly; on an asymmetric body the mirror would stand on another body."""
    flip = np.array([-1.0, 1.0, 1.0])
    offsets = np.asarray(body.skeleton.offsets, np.float64)
    if np.abs(offsets[list(MIRROR_JOINTS)] * flip - offsets).max() > tolerance:
        return False
    by_name = {c.name: c for c in body.capsules}
    for c in body.capsules:
        other = by_name.get(_mirror_name(c.name))
        if other is None or abs(other.radius - c.radius) > tolerance:
            return False
        ends = np.array([c.a, c.b]) * flip
        if min(np.abs(ends - np.array([other.a, other.b])).max(), np.abs(ends[::-1] - np.array([other.a, other.b])).max()) > tolerance:
            return False
    return True


# a body whose left and right differ by less is made exactly symmetric: anny's bodies are, but their
# fitted capsules differ side to side by up to 1 cm in a bone and 2.5 cm in a shoulder's radius
# (the vertices between shoulder and upper arm split differently on each side)
NEARLY_SYMMETRIC_M = 0.03


def symmetrized(body: BodyModel, tolerance: float = NEARLY_SYMMETRIC_M) -> BodyModel:
    """``body`` with left and right averaged, where they differ by less than ``tolerance`` (made
    exact, its sequences can be mirrored); else ``body`` as it is."""
    from dataclasses import replace

    from ..motion.skeleton import Skeleton

    flip = np.array([-1.0, 1.0, 1.0])
    offsets = np.asarray(body.skeleton.offsets, np.float64)
    mirrored_offsets = offsets[list(MIRROR_JOINTS)] * flip
    by_name = {c.name: c for c in body.capsules}
    if np.abs(mirrored_offsets - offsets).max() > tolerance or any(_mirror_name(c.name) not in by_name for c in body.capsules):
        return body
    capsules = []
    for c in body.capsules:
        other = by_name[_mirror_name(c.name)]
        mine, theirs = np.array([c.a, c.b]), np.array([other.a, other.b]) * flip
        if other is c:  # a capsule across the midline mirrors onto itself with its ends swapped
            theirs = theirs[::-1] if np.abs(theirs[::-1] - mine).max() < np.abs(theirs - mine).max() else theirs
        if np.abs(theirs - mine).max() > tolerance or abs(other.radius - c.radius) > tolerance:
            return body
        ends = 0.5 * (mine + theirs)
        capsules.append(replace(c, a=tuple(float(v) for v in ends[0]), b=tuple(float(v) for v in ends[1]),
                                radius=0.5 * (c.radius + other.radius)))
    skeleton = Skeleton(offsets=(0.5 * (offsets + mirrored_offsets)).astype(np.float32))
    return replace(body, capsules=tuple(capsules), skeleton=skeleton)


def _mirror_name(name: str) -> str:
    if name.startswith("l_"):
        return "r_" + name[2:]
    if name.startswith("r_"):
        return "l_" + name[2:]
    return name
