"""Tiny skinned bodies for the colliders' tests: a capped cylinder on two joints, bent at its elbow,
and the same cylinder on a chain of joints, curled; the mannequin's capsule surface with its thighs
bulging out of their capsules."""

import numpy as np

from hrr_garment.body.mesh_distance import vertex_normals
from hrr_garment.body.skinned_body import SkinnedBody
from hrr_garment.motion.rotations import axis_angle_to_matrix

LENGTH, RADIUS, ELBOW = 0.4, 0.05, 0.2  # a limb along +x, its joint halfway


def _cylinder(rings: int = 41, sides: int = 24) -> tuple[np.ndarray, np.ndarray]:
    """A closed cylinder along +x (by default rings 1 cm apart, 24 sides, capped): vertices and faces."""
    x = np.linspace(0.0, LENGTH, rings)
    angle = np.linspace(0.0, 2 * np.pi, sides, endpoint=False)
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
    return vertices, np.array(faces)


def skinned_limb(rings: int = 41, sides: int = 24) -> SkinnedBody:
    """The cylinder skinned to two joints, at x = 0 and at the elbow, blending over 10 cm about
    the elbow; ``rings`` and ``sides`` coarser for a game's low-poly limb."""
    vertices, faces = _cylinder(rings, sides)
    second = np.clip((vertices[:, 0] - (ELBOW - 0.05)) / 0.1, 0.0, 1.0)
    return SkinnedBody(
        vertices,
        faces,
        np.stack([1.0 - second, second], 1),
        np.broadcast_to(np.eye(3), (2, 3, 3)).copy(),
        np.array([[0.0, 0.0, 0.0], [ELBOW, 0.0, 0.0]]),
    )


def skinned_chain(joints: int) -> SkinnedBody:
    """The cylinder skinned to ``joints`` joints spaced evenly along it, each vertex blended between
    the two joints it lies between (linearly, as broadly as anny's blended skin)."""
    vertices, faces = _cylinder()
    at = np.linspace(0.0, LENGTH, joints + 1)[:-1]
    weights = np.stack([np.interp(vertices[:, 0], at, np.eye(joints)[j]) for j in range(joints)], 1)
    return SkinnedBody(
        vertices,
        faces,
        weights,
        np.broadcast_to(np.eye(3), (joints, 3, 3)).copy(),
        np.stack([at, np.zeros(joints), np.zeros(joints)], 1),
    )


def curled(body: SkinnedBody, degrees: float, twist: float) -> tuple[np.ndarray, np.ndarray]:
    """Global rotations and positions of a chain's joints, each turned ``degrees`` about z and
    ``twist`` degrees about its bone from its parent."""
    turn = axis_angle_to_matrix(np.array([0.0, 0.0, np.radians(degrees)])) @ axis_angle_to_matrix(
        np.array([np.radians(twist), 0.0, 0.0])
    )
    rot, pos = [np.eye(3)], [body.rest_positions[0]]
    for j in range(1, len(body.rest_positions)):
        pos.append(pos[-1] + rot[-1] @ (body.rest_positions[j] - body.rest_positions[j - 1]))
        rot.append(rot[-1] @ turn)
    return np.stack(rot), np.stack(pos)


def bent(degrees: float) -> tuple[np.ndarray, np.ndarray]:
    """Joint rotations and positions with the elbow bent about z."""
    return np.stack([np.eye(3), axis_angle_to_matrix(np.array([0.0, 0.0, np.radians(degrees)]))]), np.array(
        [[0.0, 0.0, 0.0], [ELBOW, 0.0, 0.0]]
    )


def turned_halves(body: SkinnedBody, degrees: float) -> tuple[np.ndarray, np.ndarray]:
    """A two-joint body's (:func:`bumpy_ball`'s) second joint turned ``degrees`` about z, in place."""
    turn = axis_angle_to_matrix(np.array([0.0, 0.0, np.radians(degrees)]))
    return np.stack([np.eye(3), turn]), body.rest_positions.copy()


def near_surface(body: SkinnedBody, posed: np.ndarray, count: int = 300):
    """Points at ``count`` posed vertices and 5 and 20 mm along their normals both ways, with their rest x."""
    normals = vertex_normals(posed, body.faces)
    offsets = np.array([-0.02, -0.005, 0.0, 0.005, 0.02])
    pick = np.random.default_rng(0).choice(len(posed) - 2, count, replace=False)  # not the caps' centres
    off = np.tile(offsets, len(pick))
    idx = np.repeat(pick, len(offsets))
    return posed[idx] + off[:, None] * normals[idx], body.vertices[idx, 0]


def probes(body: SkinnedBody, posed: np.ndarray, seed: int = 0) -> np.ndarray:
    """Points where a collider is asked: near the posed skin (:func:`near_surface` at 60 vertices)
    and 400 anywhere about the body's middle, in its grid and beyond it, each 0.1 mm off the
    vertices' ties (where two faces are equally near)."""
    rng = np.random.default_rng(seed)
    around = (rng.uniform(-0.15, 0.15, (400, 3)) * [2.0, 1.0, 1.0]) + posed.mean(0)
    points = np.concatenate([near_surface(body, posed, count=60)[0], around])
    return points + rng.normal(scale=1e-4, size=points.shape)


class BulgingMannequin:
    """The mannequin's capsule surface as a rest mesh in its T-pose, each thigh's front pushed forward
    by up to ``bulge_m`` (and every capsule's radius ``grow_m`` larger), each vertex skinned rigidly to
    its capsule's joint: it differs from the capsules only by the bulges (and the growth).
    ``vertices``, ``faces``, ``joints`` and ``weights`` as a skinned body's rest
    (:func:`~hrr_garment.body.skinned_body.skinned_body`) and a body.json mesh take them."""

    def __init__(self, bulge_m: float, grow_m: float = 0.0):
        from hrr_garment.body.capsules import DEFAULT_BODY, body_mesh, capsule_signed_distance
        from hrr_garment.motion.skeleton import JOINT_INDEX

        a, b = DEFAULT_BODY.rest_pose()
        self.vertices, self.faces = body_mesh(a, b, DEFAULT_BODY.radii + grow_m, 12, 6)
        self.joints = DEFAULT_BODY.rest_joints()
        _, _, capsule = capsule_signed_distance(self.vertices, a, b, radii=DEFAULT_BODY.radii + grow_m)
        self.capsule = capsule
        thigh = np.array([DEFAULT_BODY.capsules[c].name.endswith("thigh") for c in capsule])
        front = self.vertices[:, 2] - 0.5 * (a[capsule, 2] + b[capsule, 2])
        self.vertices[:, 2] += np.where(thigh, bulge_m * np.clip(front / 0.075, 0.0, 1.0), 0.0)
        self.weights = np.zeros((len(self.vertices), 22))
        joints = [JOINT_INDEX[DEFAULT_BODY.capsules[c].joint] for c in capsule]
        self.weights[np.arange(len(self.weights)), joints] = 1.0

    def skinned(self) -> SkinnedBody:
        from hrr_garment.body.capsules import DEFAULT_BODY
        from hrr_garment.body.skinned_body import skinned_body

        return skinned_body(DEFAULT_BODY.skeleton, self, self.weights)

    def closed(self) -> "BulgingMannequin":
        """The same with each capsule's poles, which the capsule mesh keeps as rings of copies of one
        point, welded into one vertex: a closed surface (the push-out's broad phase needs one)."""
        key = np.column_stack([np.round(self.vertices, 9), self.capsule])
        _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
        faces = inverse.ravel()[self.faces]
        keep = (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 2] != faces[:, 0])
        self.vertices, self.capsule, self.weights = (
            self.vertices[first],
            self.capsule[first],
            self.weights[first],
        )
        self.faces = faces[keep]
        return self


def _icosphere(subdivisions: int) -> tuple[np.ndarray, np.ndarray]:
    """A unit icosphere: vertices on the sphere and faces wound outward."""
    t = (1.0 + np.sqrt(5.0)) / 2.0
    v = [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t]]
    v += [[0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]]
    faces = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4]]
    faces += [[11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8]]
    faces += [[3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    vertices = [np.array(p, float) / np.linalg.norm(p) for p in v]
    for _ in range(subdivisions):
        middle: dict = {}

        def mid(a: int, b: int) -> int:
            key = (min(a, b), max(a, b))
            if key not in middle:
                p = vertices[a] + vertices[b]
                vertices.append(p / np.linalg.norm(p))
                middle[key] = len(vertices) - 1
            return middle[key]

        finer = []
        for a, b, c in faces:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            finer += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        faces = finer
    return np.array(vertices), np.array(faces)


def bumpy_ball(radius: float = 0.1, bumps: float = 0.4, seed: int = 0) -> SkinnedBody:
    """A coarse closed mesh with saddles and hollows, as a low-poly game character's crotch and armpits
    have: an icosphere (162 vertices) each pushed in or out along its ray by up to ``bumps`` of the
    ``radius`` (star-shaped about its centre, so it never crosses itself), skinned to two joints
    blended across its middle."""
    unit, faces = _icosphere(2)
    scale = 1.0 + np.random.default_rng(seed).uniform(-bumps, bumps, len(unit))
    vertices = radius * unit * scale[:, None]
    second = np.clip(0.5 + vertices[:, 0] / radius, 0.0, 1.0)
    return SkinnedBody(
        vertices,
        faces,
        np.stack([1.0 - second, second], 1),
        np.broadcast_to(np.eye(3), (2, 3, 3)).copy(),
        np.array([[-0.5 * radius, 0.0, 0.0], [0.5 * radius, 0.0, 0.0]]),
    )
