"""A tiny skinned body for the colliders' tests: a capped cylinder on two joints, bent at its elbow."""

import numpy as np

from hrr_garment.body.mesh_distance import vertex_normals
from hrr_garment.body.skinned_body import SkinnedBody
from hrr_garment.motion.rotations import axis_angle_to_matrix

LENGTH, RADIUS, ELBOW = 0.4, 0.05, 0.2  # a limb along +x, its joint halfway


def skinned_limb() -> SkinnedBody:
    """A closed cylinder (rings 1 cm apart, 24 sides, capped) skinned to two joints, at x = 0 and
    at the elbow, blending over 10 cm about the elbow."""
    x = np.linspace(0.0, LENGTH, 41)
    angle = np.linspace(0.0, 2 * np.pi, 24, endpoint=False)
    ring = np.stack([np.zeros_like(angle), RADIUS * np.cos(angle), RADIUS * np.sin(angle)], 1)
    vertices = np.concatenate([(ring + [xi, 0.0, 0.0]) for xi in x] + [[[0.0, 0, 0], [LENGTH, 0, 0]]])
    n, s = len(x), len(angle)
    faces = []
    for i in range(n - 1):
        for k in range(s):
            a, b, c, d = i * s + k, i * s + (k + 1) % s, (i + 1) * s + k, (i + 1) * s + (k + 1) % s
            faces += [[a, b, d], [a, d, c]]
    for k in range(s):
        faces += [[n * s, (k + 1) % s, k], [n * s + 1, (n - 1) * s + k, (n - 1) * s + (k + 1) % s]]
    second = np.clip((vertices[:, 0] - (ELBOW - 0.05)) / 0.1, 0.0, 1.0)
    return SkinnedBody(
        vertices,
        np.array(faces),
        np.stack([1.0 - second, second], 1),
        np.broadcast_to(np.eye(3), (2, 3, 3)).copy(),
        np.array([[0.0, 0.0, 0.0], [ELBOW, 0.0, 0.0]]),
    )


def bent(degrees: float) -> tuple[np.ndarray, np.ndarray]:
    """Joint rotations and positions with the elbow bent about z."""
    return np.stack([np.eye(3), axis_angle_to_matrix(np.array([0.0, 0.0, np.radians(degrees)]))]), np.array(
        [[0.0, 0.0, 0.0], [ELBOW, 0.0, 0.0]]
    )


def near_surface(body: SkinnedBody, posed: np.ndarray, count: int = 300):
    """Points at ``count`` posed vertices and 5 and 20 mm along their normals both ways, with their rest x."""
    normals = vertex_normals(posed, body.faces)
    offsets = np.array([-0.02, -0.005, 0.0, 0.005, 0.02])
    pick = np.random.default_rng(0).choice(len(posed) - 2, count, replace=False)  # not the caps' centres
    off = np.tile(offsets, len(pick))
    idx = np.repeat(pick, len(offsets))
    return posed[idx] + off[:, None] * normals[idx], body.vertices[idx, 0]
