"""The bodies of a dataset as its HDF5 file keeps them (``/bodies/<name>``): each body's record and
the garment's rest shape on it. A dataset simulated on bodies other than the mannequin keeps each of
them (:mod:`.dataset`), and each sequence names the body it was simulated on."""

from __future__ import annotations

import json

import numpy as np

from ..body.body_file import body_from_dict, body_to_dict
from ..body.mannequin import MANNEQUIN, mannequin_record
from ..garment.dressing import DressedBody
from ..garment.mesh import GarmentMesh


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
