"""The built-in garments' shapes: a :class:`TubeShape` per named template (heights, flare, pleats,
hem asymmetry, straps), and a shape made for the mannequin mapped onto another body by its
landmarks' heights."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..body.capsules import DEFAULT_BODY, BodyModel
from ..motion.skeleton import JOINT_INDEX


@dataclass(frozen=True)
class TubeShape:
    """One tube garment. Heights in metres above the ground in the rest pose."""

    top: float  # top edge height
    waist: float  # where flaring may begin (rows above follow the body exactly)
    hem: float  # mean hem height
    flare: float  # tan of the skirt's half-angle below the waist
    gap: float = 0.012  # cloth-to-body clearance
    hem_tilt: float = 0.0  # asymmetric hem: height varies by +-hem_tilt around the tube
    hem_tilt_angle: float = 0.0  # angle (rad) of the lowest point of the hem
    pleats: int = 0  # number of knife pleats (0: plain)
    pleat_depth: float = 0.0  # radial depth of a pleat at the hem, metres
    attach_band: float = 0.025  # rows within this distance below the top edge are the waistband
    straps: bool = False
    strap_x: float = 0.10  # strap centre line, metres from the body's midline
    strap_width: float = 0.035
    shoulder_band: float = 0.03  # strap vertices this close to the strap's top are attached


GARMENT_SHAPES: dict[str, TubeShape] = {
    "dress": TubeShape(top=1.30, waist=1.10, hem=0.50, flare=0.42, straps=True, attach_band=0.0),
    "skirt": TubeShape(top=1.05, waist=1.05, hem=0.56, flare=0.38),
    "pleated_skirt": TubeShape(top=1.04, waist=1.04, hem=0.60, flare=0.30, pleats=16, pleat_depth=0.03),
    "asymmetric_skirt": TubeShape(
        top=1.05, waist=1.05, hem=0.58, flare=0.40, hem_tilt=0.16, hem_tilt_angle=np.pi * 0.75
    ),
}
GARMENT_NAMES: tuple[str, ...] = tuple(GARMENT_SHAPES)


# heights of the body's landmarks in the rest pose: the ground, the knees, the pelvis, the upper
# spine, the shoulders; a template's heights between two of them keep their place between them
LANDMARKS = (("l_knee", "r_knee"), ("pelvis",), ("spine3",), ("l_shoulder", "r_shoulder"))


def _landmark_heights(body: BodyModel) -> np.ndarray:
    """The heights of :data:`LANDMARKS` on ``body`` at rest, the ground first."""
    joints = body.rest_joints()
    return np.array([0.0, *[np.mean([joints[JOINT_INDEX[j], 1] for j in group]) for group in LANDMARKS]])


def shape_for_body(shape: TubeShape, body: BodyModel) -> TubeShape:
    """``shape`` (made for the mannequin) on ``body``: each height mapped between the body's
    landmarks (:data:`LANDMARKS`) as it lies between the mannequin's, the strap line moved with the
    shoulders' width. The mannequin's own shape is returned as it is."""
    if body.is_mannequin_frame:
        return shape
    ours, theirs = _landmark_heights(DEFAULT_BODY), _landmark_heights(body)

    def height(y: float) -> float:  # piecewise linear, extended above the shoulders by the last ratio
        if y <= ours[-1]:
            return float(np.interp(y, ours, theirs))
        return float(theirs[-1] + (y - ours[-1]) * (theirs[-1] - theirs[-2]) / (ours[-1] - ours[-2]))

    joints, mannequin = body.rest_joints(), DEFAULT_BODY.rest_joints()
    shoulders = abs(joints[JOINT_INDEX["l_shoulder"], 0]) / abs(mannequin[JOINT_INDEX["l_shoulder"], 0])
    tilt = 0.5 * (
        height(shape.hem + shape.hem_tilt) - height(shape.hem - shape.hem_tilt)
    )  # the hem's span, mapped
    return replace(
        shape,
        top=height(shape.top),
        waist=height(shape.waist),
        hem=height(shape.hem),
        hem_tilt=tilt,
        strap_x=shape.strap_x * shoulders,
    )
