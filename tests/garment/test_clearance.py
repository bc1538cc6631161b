"""A garment dressed on a body whose visible mesh is not round keeps its clearance from that mesh:
nothing inside, nothing nearer than 12 mm, the waistband resting at the clearance, the hem where the
template put it, the cloth smooth and still symmetric; without a mesh nothing moves."""

import numpy as np

from hrr_garment.body.capsules import DEFAULT_BODY
from hrr_garment.body.mannequin import mannequin_record
from hrr_garment.body.mesh_distance import mesh_signed_distance
from hrr_garment.body.skinned_body import SkinnedBody
from hrr_garment.garment.clearance import CLEARANCE_M
from hrr_garment.garment.dressing import dress
from hrr_garment.garment.mesh import mirror_map
from hrr_garment.garment.templates import make_garment
from hrr_garment.garment.visible_surface import VisibleSurface, rest_mesh
from hrr_garment.motion.rotations import axis_angle_to_matrix
from hrr_garment.motion.skeleton import JOINT_INDEX

# an egg of a torso round the mannequin's hips: 3 cm wider than its capsules at the waist, 2 cm
# slimmer behind (the skirt's waistband, made for the capsules, lies inside it at the sides and
# stands off it behind)
CENTRE, SEMI_AXES = np.array([0.0, 1.0, 0.0]), np.array([0.16, 0.22, 0.105])


def _ellipsoid(rings: int = 24, segments: int = 32) -> tuple[np.ndarray, np.ndarray]:
    """A closed ellipsoid mesh, wound outward: two poles and ``rings`` rings of ``segments``."""
    polar = np.pi * np.arange(1, rings + 1) / (rings + 1)
    azimuth = 2 * np.pi * np.arange(segments) / segments
    p, a = np.meshgrid(polar, azimuth, indexing="ij")
    ring = np.stack([np.sin(p) * np.sin(a), np.cos(p), np.sin(p) * np.cos(a)], -1).reshape(-1, 3)
    unit = np.concatenate([[[0.0, 1.0, 0.0]], ring, [[0.0, -1.0, 0.0]]])
    faces = []
    for s in range(segments):
        t = (s + 1) % segments
        faces.append([0, 1 + t, 1 + s])
        last = 1 + (rings - 1) * segments
        faces.append([len(unit) - 1, last + s, last + t])
        for r in range(rings - 1):
            a0, a1, b0, b1 = (
                1 + r * segments + s,
                1 + r * segments + t,
                1 + (r + 1) * segments + s,
                1 + (r + 1) * segments + t,
            )
            faces += [[a0, a1, b0], [a1, b1, b0]]
    return CENTRE + unit * SEMI_AXES, np.array(faces, np.int64)


def _egg_body() -> SkinnedBody:
    """The ellipsoid skinned rigidly to the mannequin's pelvis, standing in its rest pose."""
    vertices, faces = _ellipsoid()
    weights = np.zeros((len(vertices), 22))
    weights[:, JOINT_INDEX["pelvis"]] = 1.0
    joints = DEFAULT_BODY.rest_joints().astype(np.float64)
    return SkinnedBody(vertices, faces, weights, np.broadcast_to(np.eye(3), (22, 3, 3)).copy(), joints)


def test_a_skirt_keeps_its_clearance_from_a_mesh_that_is_not_round():
    egg = _egg_body()
    assert np.abs(rest_mesh(egg, DEFAULT_BODY) - egg.vertices).max() < 1e-9  # it stands where it is dressed
    skirt = make_garment("skirt", 200)
    on_capsules, _ = dress("egg", mannequin_record(), skirt, made_for=DEFAULT_BODY, visible=None)
    placed, report = dress("egg", mannequin_record(), skirt, made_for=DEFAULT_BODY, visible=egg)
    before = mesh_signed_distance(on_capsules.garment.vertices, egg.vertices, egg.faces)
    after = mesh_signed_distance(placed.garment.vertices, egg.vertices, egg.faces)
    assert (before < 0).mean() > 0.03 and report.visible.inside == (before < 0).mean()
    assert after.min() > CLEARANCE_M - 5e-4  # nothing inside, nothing nearer than the clearance
    band = skirt.attached
    assert before[band].max() > CLEARANCE_M + 0.015  # the band stood off the mesh behind
    assert np.abs(after[band] - CLEARANCE_M).max() < 0.002  # and rests on it now all round
    hem = skirt.groups["hem"]
    moved = np.linalg.norm(placed.garment.vertices - on_capsules.garment.vertices, axis=1)
    assert moved[hem].max() < 1e-3  # the hem, far below the mesh, keeps the template's line
    # smooth: each edge within 30 % of its length on the capsules (a dent or a spike would fold it)
    e = skirt.edges()
    length = [
        np.linalg.norm(v[e[:, 0]] - v[e[:, 1]], axis=1)
        for v in (on_capsules.garment.vertices, placed.garment.vertices)
    ]
    assert 0.7 < (length[1] / length[0]).min() and (length[1] / length[0]).max() < 1.3
    perm = mirror_map(skirt.vertices)
    mirrored = placed.garment.vertices[perm] * [-1.0, 1.0, 1.0]
    assert np.abs(mirrored - placed.garment.vertices).max() < 1e-6  # still symmetric: clips can be mirrored


def test_the_surface_tracks_inside_and_outside_as_points_move():
    egg = _egg_body()
    surface = VisibleSurface(egg.vertices, egg.faces)
    points = CENTRE + np.array([[0.0, 0.0, 0.0], [0.3, 0.0, 0.0], [0.15, 0.0, 0.0], [0.0, 0.0, 0.2]])
    for step in np.linspace(0.0, 0.25, 6):  # all walked out along +x, through the mesh's side
        moved = points + [step, 0.0, 0.0]
        distance, direction = surface.signed(moved)
        exact = mesh_signed_distance(moved, egg.vertices, egg.faces)
        assert np.allclose(distance, exact, atol=1e-9)
        assert np.allclose(np.linalg.norm(direction, axis=1), 1.0)


def test_without_a_visible_mesh_the_garment_stays_where_its_capsules_put_it():
    skirt = make_garment("skirt", 200)
    default, report = dress("m", mannequin_record(), skirt, made_for=DEFAULT_BODY)  # the mannequin: no mesh
    none, _ = dress("m", mannequin_record(), skirt, made_for=DEFAULT_BODY, visible=None)
    assert report.visible is None and np.array_equal(default.garment.vertices, none.garment.vertices)


def test_the_mesh_is_skinned_into_the_pose_the_garment_is_dressed_in():
    """A mesh modelled with its arm 45 degrees down (anny's A-pose) stands in the body's T-pose."""
    joints = DEFAULT_BODY.rest_joints().astype(np.float64)
    shoulder, wrist = (JOINT_INDEX[j] for j in ("l_shoulder", "l_wrist"))
    down = axis_angle_to_matrix(np.array([0.0, 0.0, -np.pi / 4]))
    hand = joints[shoulder] + down @ (joints[wrist] - joints[shoulder])  # where the A-pose holds the hand
    rotations = np.broadcast_to(np.eye(3), (22, 3, 3)).copy()
    rotations[shoulder] = down
    weights = np.zeros((1, 22))
    weights[0, shoulder] = 1.0
    arm = SkinnedBody(hand[None], np.zeros((1, 3), np.int64), weights, rotations, joints)
    assert np.abs(hand - joints[wrist]).max() > 0.1
    assert np.abs(rest_mesh(arm, DEFAULT_BODY)[0] - joints[wrist]).max() < 1e-9
