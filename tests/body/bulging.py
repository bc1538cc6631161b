"""A body whose visible mesh is not its capsules: the mannequin's capsule surface with each thigh's
front pushed forward by up to ``BULGE_M``, skinned rigidly to the capsules' joints (the simulator's
and the push-out's tests on the visible body)."""

import numpy as np

from hrr_garment.body.capsules import DEFAULT_BODY, body_mesh, capsule_signed_distance
from hrr_garment.body.skinned_body import SkinnedBody, skinned_body
from hrr_garment.motion.skeleton import JOINT_INDEX

BULGE_M = 0.05  # how far the thighs' fronts stand out of their capsules


class _Rest:
    """The mannequin's capsule surface, each thigh's front pushed forward by up to ``bulge``."""

    def __init__(self, bulge: float):
        a, b = DEFAULT_BODY.rest_pose()
        self.vertices, self.faces = body_mesh(a, b, DEFAULT_BODY.radii, 12, 6)
        self.joints = DEFAULT_BODY.rest_joints()
        _, _, self.capsule = capsule_signed_distance(self.vertices, a, b, radii=DEFAULT_BODY.radii)
        thigh = np.array([DEFAULT_BODY.capsules[c].name.endswith("thigh") for c in self.capsule])
        front = self.vertices[:, 2] - 0.5 * (a[self.capsule, 2] + b[self.capsule, 2])
        self.vertices[:, 2] += np.where(thigh, bulge * np.clip(front / 0.075, 0.0, 1.0), 0.0)


def bulging_body(bulge: float = BULGE_M) -> SkinnedBody:
    """That surface skinned rigidly, each vertex to its capsule's joint: it differs from the capsules
    only by the bulges."""
    return _skinned(_Rest(bulge))


def closed_bulging_body(bulge: float = BULGE_M) -> SkinnedBody:
    """The same with each capsule's poles, which the capsule mesh keeps as rings of copies of one
    point, welded into one vertex: a closed surface (the push-out's broad phase needs one)."""
    rest = _Rest(bulge)
    key = np.column_stack([np.round(rest.vertices, 9), rest.capsule])
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    faces = inverse.ravel()[rest.faces]
    keep = (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 2] != faces[:, 0])
    rest.vertices, rest.capsule, rest.faces = rest.vertices[first], rest.capsule[first], faces[keep]
    return _skinned(rest)


def _skinned(rest: _Rest) -> SkinnedBody:
    weights = np.zeros((len(rest.vertices), 22))
    joints = [JOINT_INDEX[DEFAULT_BODY.capsules[c].joint] for c in rest.capsule]
    weights[np.arange(len(weights)), joints] = 1.0
    return skinned_body(DEFAULT_BODY.skeleton, rest, weights)
