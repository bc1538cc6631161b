"""The "reflect" mirror mode: every sequence's left-right mirror image made from its source's
simulation (the garment's vertices permuted and flipped, the motion mirrored), joining its source's
split; skipped for a template, or a body, that is not its own mirror image."""

from __future__ import annotations

import numpy as np

from ..body.symmetry import is_symmetric
from ..data.dataset import SequenceRecord
from ..data.splits import MIRROR_SUFFIX
from ..garment.dressing import DressedBody
from ..garment.mesh import GarmentMesh, mirror_map


def add_reflected_mirrors(
    records: list[SequenceRecord],
    split: dict[str, list[str]],
    garment: GarmentMesh,
    progress: bool,
    bodies: dict[str, DressedBody] | None = None,
) -> tuple[list[SequenceRecord], dict[str, list[str]]]:
    """``records`` with their reflected mirrors added, and ``split`` with each mirror beside its source."""
    perm = mirror_map(garment.vertices)
    if perm is None:
        if progress:
            print(f"not mirroring: the {garment.name} template is not symmetric about x = 0")
        return records, split
    # a body that is not its own mirror image would stand on another body in the mirror
    asymmetric = {
        n
        for n, b in (bodies or {}).items()
        if not (is_symmetric(b.body) and mirror_map(b.garment.vertices) is not None)
    }
    if asymmetric and progress:
        print(
            f"not mirroring the sequences on {len(asymmetric)} asymmetric bod(y/ies): "
            f"{sorted(asymmetric)[:3]}"
        )
    flip = np.array([-1.0, 1.0, 1.0], np.float32)
    mirrored = [
        SequenceRecord(
            f"{r.name}{MIRROR_SUFFIX}",
            r.garment[:, perm] * flip,
            r.motion.mirrored(),
            info={**r.info, "mirror_of": r.name},
            body_name=r.body_name,
        )
        for r in records
        if r.body_name not in asymmetric
    ]
    names = {r.name for r in records if r.body_name not in asymmetric}
    return records + mirrored, {
        k: sorted(v + [f"{n}{MIRROR_SUFFIX}" for n in v if n in names]) for k, v in split.items()
    }
