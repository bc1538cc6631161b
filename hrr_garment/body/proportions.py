"""A performer's proportions, and the parametric body nearest to them.

Retargeting keeps a clip's pose and throws its performer's proportions away: every clip plays on
the mannequin. These measures keep them. Each is the distance between two canonical joints that
move rigidly together (a bone, or two joints hung from one parent: the hips from the pelvis, the
collars from the upper spine), so it does not depend on the pose; a rig whose canonical joints
skip joints of its own (a longer spine) bends a little between them, which the median over the
clip's frames absorbs.

    measures = source_proportions("02_01.bvh")    # metres, the rig's own, from the file
    nearest = nearest_body(measures)               # NearestBody: shape, each measure's error
    nearest.shape                                  # a BodyShape for parametric_body()

:func:`nearest_body` descends through anny's joints (differentiable) from its average adult to the
phenotype whose measures come closest (sum of squared differences), and reports each measure's
difference, in millimetres, and their root mean square.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..motion.skeleton import JOINT_INDEX, JOINT_NAMES, MIRROR_JOINTS
from .parametric import BodyShape

# name: the joints (left side, mirrored for the right and averaged; or a left-right pair). Only
# joints that every rig puts at the same anatomical place: the limbs' hinges, the hips and the
# shoulders (the upper arms' heads). Where a rig starts its collars, spine and neck is its own
# convention (CMU's collars start where its spine ends, 20 cm from the shoulder; Mixamo's 10 cm),
# so those would measure the rig, not the performer. The shoulders' width moves a little with the
# collars: its median over the clip's frames is the performer's (without it, a performer's arms
# played on a narrower body reach across its torso: docs/bodies.md).
# Not every rig's hips and shoulders are a person's, though: the Bandai-Namco rig's are 13 and 20 cm
# apart, so the performer's body (.performer) takes only the limbs from the rig.
MEASURES = {
    "upper_leg": ("l_hip", "l_knee"),
    "lower_leg": ("l_knee", "l_ankle"),
    "upper_arm": ("l_shoulder", "l_elbow"),
    "forearm": ("l_elbow", "l_wrist"),
    "hip_width": ("l_hip", "r_hip"),
    "shoulder_width": ("l_shoulder", "r_shoulder"),
}
MIN_MEASURE_M = 0.01  # shorter: two of the rig's joints at one place, not a measure of the performer
NEAREST_STEPS = 200  # Adam steps on the phenotype's logits (a second or two)


def joint_pairs(measure: str) -> list[tuple[int, int]]:
    """The joint index pairs whose distances, averaged, make ``measure``: a left-right pair itself,
    or a left side's joints and their mirror images (:data:`~hrr_garment.motion.skeleton.MIRROR_JOINTS`)."""
    a, b = (JOINT_INDEX[j] for j in MEASURES[measure])
    return [(a, b)] if MIRROR_JOINTS[a] == b else [(a, b), (MIRROR_JOINTS[a], MIRROR_JOINTS[b])]


def proportions(joint_positions: np.ndarray) -> dict[str, float]:
    """The measures (metres) of canonical joint positions (T, 22, 3) or (22, 3): the median over
    frames, left and right sides averaged."""
    p = np.asarray(joint_positions, np.float64)
    p = p[None] if p.ndim == 2 else p
    return {
        name: float(
            np.median(
                np.mean([np.linalg.norm(p[:, x] - p[:, y], axis=-1) for x, y in joint_pairs(name)], axis=0)
            )
        )
        for name in MEASURES
    }


def source_proportions(path: str | Path, unit_scale: float | None = None) -> dict[str, float]:
    """The performer's measures from a BVH or glTF / GLB file's own rig (metres)."""
    from ..motion.bvh_motion import bvh_source
    from ..motion.gltf import GltfSettings, gltf_source
    from ..motion.gltf_file import GLTF_SUFFIXES

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".bvh":
        src, _, mapping, _ = bvh_source(path, unit_scale)
    elif suffix in GLTF_SUFFIXES:
        src, _, mapping, _ = gltf_source(path, GltfSettings(unit_scale=unit_scale))
    else:
        raise InputError(
            path, "a performer's proportions come from a BVH or glTF / GLB rig (npz files carry none)"
        )
    names = [n for n in JOINT_INDEX if n in mapping]
    needed = {JOINT_NAMES[j] for m in MEASURES for pair in joint_pairs(m) for j in pair}
    missing = sorted(needed - set(names))
    if missing:
        raise InputError(path, f"the rig has no joints for {missing}: its proportions cannot be measured")
    positions = np.zeros((len(src.global_positions), len(JOINT_INDEX), 3))
    for name in names:
        positions[:, JOINT_INDEX[name]] = src.global_positions[:, mapping[name]]
    # a measure whose joints coincide on this rig says nothing of the performer
    return {k: v for k, v in proportions(positions).items() if v >= MIN_MEASURE_M}


@dataclass(frozen=True)
class NearestBody:
    """The parametric shape whose measures come closest to a performer's, and by how much."""

    shape: BodyShape
    errors_mm: dict[str, float]  # each measure's difference, body minus performer
    rms_mm: float


def nearest_body(measures: dict[str, float], steps: int = NEAREST_STEPS) -> NearestBody:
    """The phenotype whose rest joints' :data:`MEASURES` come closest to ``measures`` (metres)."""
    import torch

    from .parametric import _rest_tensors

    unknown = sorted(set(measures) - set(MEASURES))
    bad = [
        k
        for k, v in measures.items()
        if not (isinstance(v, (int, float)) and np.isfinite(v) and 0.01 < v < 2.0)
    ]
    if unknown or bad or not measures:
        raise ValueError(
            f"measures must be some of {list(MEASURES)} in metres (0.01-2 m); unknown {unknown}, bad {bad}"
        )
    names = [f.name for f in fields(BodyShape)]
    keys = list(measures)
    target = torch.tensor([measures[k] for k in keys], dtype=torch.float32)
    logits = torch.zeros(len(names), requires_grad=True)
    optimiser = torch.optim.Adam([logits], lr=0.08)

    def model_measures(values):
        _, joints = _rest_tensors({n: values[i : i + 1] for i, n in enumerate(names)})
        return torch.stack(
            [
                torch.stack([torch.linalg.norm(joints[x] - joints[y]) for x, y in joint_pairs(k)]).mean()
                for k in keys
            ]
        )

    for _ in range(steps):
        loss = ((model_measures(torch.sigmoid(logits)) - target) ** 2).sum()
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
    values = torch.sigmoid(logits).detach()
    with torch.no_grad():
        errors = (model_measures(values) - target).numpy() * 1000
    shape = BodyShape(**{n: float(v) for n, v in zip(names, values)})
    return NearestBody(shape, {k: float(e) for k, e in zip(keys, errors)}, float(np.sqrt(np.mean(errors**2))))
