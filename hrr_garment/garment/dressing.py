"""A body and the garment on it in their rest poses (:class:`DressedBody`), and a garment carried
onto a body (:func:`dress`): by its capsules (:mod:`.transfer`), then kept clear of the mesh the
viewer sees where the body has one (:mod:`.clearance`). The garment on a body has the template's
topology (the same vertices, faces and groups) and that body's rest shape, so a sequence's strain,
its penetration and a model's predictions are measured against its own body."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np

from ..body.body_file import BodyRecord, body_to_dict
from ..body.capsules import DEFAULT_BODY, BodyModel
from ..body.skinned_body import SkinnedBody, visible_body
from ..body.symmetry import is_symmetric, symmetrized_record
from ..io_utils import strict_json
from ..motion.skeleton import REST_PELVIS_HEIGHT
from .attachment import RELAX_PASSES
from .clearance import keep_clearance
from .mesh import GarmentMesh, mirror_map
from .transfer import TransferReport, transfer_garment
from .visible_surface import VisibleSurface, rest_mesh


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
    def visible(self) -> SkinnedBody | None:
        """The mesh a viewer sees of the body, which the simulator collides the cloth with: a
        parametric body's or a fitted character's skinned mesh; None for a body drawn as its capsules
        (the mannequin)."""
        return visible_body(self.record)

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
        """A short content hash of the body (skeleton, capsules, heights, the mesh the cloth collides
        with where it has one) and the garment's rest shape: what a simulated sequence on it
        depends on (its fit report does not)."""
        # a character's own mesh is hashed as arrays, not as body.json's text of it (a second a body)
        plain = body_to_dict(replace(self.record, mesh=None))
        h = hashlib.sha1(strict_json({k: v for k, v in plain.items() if k not in ("fit", "shape")}).encode())
        skin, mesh = self.visible, self.record.mesh
        arrays = () if skin is None else (skin.vertices, skin.faces, skin.weights)
        arrays += () if mesh is None else (mesh.joints,)
        for arr in (self.garment.vertices, self.garment.faces, self.garment.attached, *arrays):
            h.update(np.ascontiguousarray(arr).tobytes())
        if skin is not None:  # its straps ride the skin whole, relaxed: parts from before are stale
            h.update(f"pins on faces, relaxed {RELAX_PASSES}, straps riding whole".encode())
        return h.hexdigest()[:16]


def dress(
    name: str,
    record: BodyRecord,
    garment: GarmentMesh,
    *,
    made_for: BodyModel,
    visible: SkinnedBody | None | Literal["auto"] = "auto",
) -> tuple[DressedBody, TransferReport]:
    """The body (left and right made exactly alike where they nearly are: its sequences can then be
    mirrored) and ``garment`` (modelled on ``made_for``) carried onto it, then kept its clearance
    off the body the viewer sees (:func:`~.clearance.keep_clearance`): ``visible``, by default the
    record's own (:func:`~hrr_garment.body.skinned_body.visible_body`: an anny body's mesh, a fitted
    character's); None, or a body without a mesh (the mannequin, whose capsules are what the viewer
    sees), keeps the garment where its capsules put it."""
    if isinstance(visible, str):  # "auto"
        visible = visible_body(record)
    record = symmetrized_record(record)
    body = record.body
    on_body, report = transfer_garment(garment, made_for=made_for, body=body)
    perm = mirror_map(garment.vertices) if is_symmetric(made_for) else None
    symmetric = perm is not None and is_symmetric(body)
    if visible is not None:
        surface = VisibleSurface(rest_mesh(visible, body), visible.faces)
        on_body, kept = keep_clearance(on_body, surface, mirror=perm if symmetric else None)
        report = replace(report, visible=kept)
    if symmetric:  # exactly symmetric, as the template was
        flip = np.array([-1.0, 1.0, 1.0], np.float32)
        on_body = replace(on_body, vertices=0.5 * (on_body.vertices + on_body.vertices[perm] * flip))
    return DressedBody(name, record, on_body), report
