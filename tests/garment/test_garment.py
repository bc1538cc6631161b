"""Garment templates, mesh checks and repairs, OBJ round trips, attachment skinning."""

from dataclasses import replace

import numpy as np
import pytest

from hrr_garment.body.capsules import DEFAULT_BODY, capsule_signed_distance
from hrr_garment.garment.attachment import bind_attached
from hrr_garment.garment.body_surface import rest_body
from hrr_garment.garment.mesh import (
    GarmentError,
    GarmentMesh,
    check_garment,
    components,
    repair_mesh,
)
from hrr_garment.garment.obj import load_garment_obj, read_obj, write_obj
from hrr_garment.garment.templates import GARMENT_NAMES, make_garment
from hrr_garment.motion.synth import synthesize


@pytest.fixture(scope="module")
def garments():
    return {(n, v): make_garment(n, v) for n in GARMENT_NAMES for v in (300, 1200)}


@pytest.mark.parametrize("name", GARMENT_NAMES)
@pytest.mark.parametrize("target", [300, 1200])
def test_template_is_a_valid_garment(garments, name, target):
    mesh = garments[(name, target)]
    check_garment(mesh)  # one component, manifold, consistent winding, no degenerate faces
    assert abs(mesh.num_vertices - target) <= 0.15 * target
    assert mesh.vertices.dtype == np.float32 and mesh.faces.dtype == np.int32
    assert len(mesh.attached) > 0 and "hem" in mesh.groups
    # Hem is the lowest ring; attached vertices sit at the top of the skirt or on the shoulders.
    assert mesh.vertices[mesh.groups["hem"], 1].max() < mesh.vertices[mesh.attached, 1].min()


@pytest.mark.parametrize("name", GARMENT_NAMES)
def test_template_sits_outside_the_body_with_outward_normals(garments, name):
    mesh = garments[(name, 1200)]
    a, b, r = rest_body()
    d, normal, _ = capsule_signed_distance(mesh.vertices.astype(np.float64), a, b, r)
    assert d.min() > 0.005  # the cloth starts clear of the body (gap 12 mm, minus discretisation)
    tri = mesh.vertices[mesh.faces].astype(np.float64)
    face_normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    centre = tri.mean(1)
    radial = centre * np.array([1.0, 0.0, 1.0])
    tube = np.isin(mesh.faces, mesh.groups.get("straps", [])).sum(1) == 0
    outward = (face_normal[tube] * radial[tube]).sum(1) > 0
    assert outward.mean() > 0.97  # pleats fold a few faces back


@pytest.mark.slow
def test_resolution_scales_and_dress_has_straps():
    small, large = make_garment("dress", 300), make_garment("dress", 4000)
    assert large.num_vertices > 10 * small.num_vertices
    assert {"straps", "shoulders", "waistband"} <= set(large.groups)
    assert large.vertices[large.groups["shoulders"], 1].min() > 1.38  # over the shoulders


def test_unknown_garment_and_too_few_vertices():
    with pytest.raises(Exception, match="unknown garment"):
        make_garment("kimono")
    with pytest.raises(Exception, match="too few"):
        make_garment("skirt", 20)


def _quad_strip(offset=0.0):
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], np.float32) + offset
    f = np.array([[0, 1, 2], [1, 3, 2]], np.int32)
    return v, f


def test_check_rejects_two_components_nonmanifold_flipped_and_unattached():
    v1, f1 = _quad_strip()
    v2, f2 = _quad_strip(5.0)
    two = GarmentMesh(
        "two", np.concatenate([v1, v2]), np.concatenate([f1, f2 + 4]), {"a": np.array([0])}, ("a",)
    )
    with pytest.raises(GarmentError, match="2 connected components"):
        check_garment(two)
    fin = GarmentMesh(
        "fin",
        np.concatenate([v1, [[0.5, 0.5, 1.0]]]).astype(np.float32),
        np.concatenate([f1, [[1, 2, 4]]]).astype(np.int32),
        {"a": np.array([0])},
        ("a",),
    )
    with pytest.raises(GarmentError, match="non-manifold"):
        check_garment(fin)
    flipped = GarmentMesh(
        "flip", v1, np.array([[0, 1, 2], [1, 2, 3]], np.int32), {"a": np.array([0])}, ("a",)
    )
    with pytest.raises(GarmentError, match="inconsistent winding"):
        check_garment(flipped)
    with pytest.raises(GarmentError, match="no attached vertices"):
        check_garment(GarmentMesh("free", v1, f1))


def test_repair_merges_duplicates_and_fixes_winding():
    mesh = make_garment("skirt", 300)
    # Split every face into its own vertices (as some exporters do) and flip every other face.
    v = mesh.vertices[mesh.faces].reshape(-1, 3)
    f = np.arange(len(v)).reshape(-1, 3)
    f[::2] = f[::2, ::-1]
    groups = {
        "waistband": np.flatnonzero(np.isin(mesh.faces.ravel(), mesh.groups["waistband"])).astype(np.int32)
    }
    broken = GarmentMesh("broken", v, f.astype(np.int32), groups, ("waistband",))
    with pytest.raises(GarmentError):
        check_garment(broken)
    fixed = repair_mesh(broken)
    check_garment(fixed)
    assert fixed.num_vertices == mesh.num_vertices
    assert len(fixed.attached) == len(mesh.attached)
    assert components(fixed.num_vertices, fixed.faces).max() == 0


def test_obj_round_trip_with_polygons_and_groups(tmp_path):
    path = tmp_path / "quad.obj"
    path.write_text(
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nv 2 1 0\n"
        "g band\nf 1/1/1 2/2/2 3/3/3 4/4/4\ng body\nf 2 5 6 3\n"
    )
    v, f, groups = read_obj(path)
    assert v.shape == (6, 3) and f.shape == (4, 3)
    mesh = load_garment_obj(path, attached_group="band")
    assert mesh.attached.tolist() == [0, 1, 2, 3]
    out = write_obj(tmp_path / "out.obj", mesh.vertices, mesh.faces, {"band": mesh.attached})
    again = load_garment_obj(out, attached_group="band")
    assert np.array_equal(again.faces, mesh.faces) and np.allclose(again.vertices, mesh.vertices)
    with pytest.raises(GarmentError, match="no group 'waist'"):
        load_garment_obj(path, attached_group="waist")


def test_skinning_reproduces_rest_pose_and_follows_rigid_motion():
    mesh = make_garment("dress", 600)
    binding = bind_attached(mesh)
    assert np.allclose(binding.weights.sum(1), 1.0)
    motion = synthesize("idle", 1.0, seed=0)
    rot = np.broadcast_to(np.eye(3), (1, 22, 3, 3))
    from hrr_garment.motion.skeleton import (
        PARENTS,
        REST_OFFSETS,
        REST_PELVIS_HEIGHT,
        rest_positions,
    )

    rest = rest_positions(REST_OFFSETS, PARENTS)[None] + [0, REST_PELVIS_HEIGHT, 0]
    assert np.allclose(binding.pose(rot, rest)[0], mesh.vertices[mesh.attached], atol=1e-6)
    shifted = binding.pose(motion.global_rotations, motion.joint_positions + [3.0, 0.0, -2.0])
    assert np.allclose(
        shifted - binding.pose(motion.global_rotations, motion.joint_positions), [3.0, 0.0, -2.0]
    )
    # Only torso joints drive attachments (an arm swing must not stretch a strap).
    from hrr_garment.motion.skeleton import JOINT_NAMES

    assert {JOINT_NAMES[j] for j in np.unique(binding.joints)} <= {
        "pelvis",
        "spine1",
        "spine2",
        "spine3",
        "neck",
        "l_collar",
        "r_collar",
    }


@pytest.mark.parametrize(
    "name,symmetric",
    [("dress", True), ("skirt", True), ("pleated_skirt", False), ("asymmetric_skirt", False)],
)
def test_mirror_map_finds_left_right_symmetry(name, symmetric):
    from hrr_garment.garment.mesh import mirror_map

    g = make_garment(name, 300)
    perm = mirror_map(g.vertices)
    assert (perm is not None) == symmetric
    if symmetric:
        assert np.allclose(g.vertices[perm] * [-1, 1, 1], g.vertices, atol=1e-6)
        assert np.array_equal(perm[perm], np.arange(g.num_vertices))  # mirroring twice is the identity


@pytest.mark.parametrize(
    "vertices",
    [300, 400, 1000, pytest.param(4000, marks=pytest.mark.slow), pytest.param(12000, marks=pytest.mark.slow)],
)  # seconds each
def test_dress_straps_pass_over_the_shoulders_not_the_head(vertices):
    """At 400 and 4,000 vertices the straps once looped over the head (1.68 m high)."""
    from hrr_garment.body.capsules import DEFAULT_BODY

    dress = make_garment("dress", vertices)
    a, b = DEFAULT_BODY.rest_pose()
    neck = [i for i, c in enumerate(DEFAULT_BODY.capsules) if c.joint == "neck"][0]
    assert dress.vertices[dress.groups["straps"], 1].max() < min(a[neck, 1], b[neck, 1]) + 0.05


def test_attached_vertices_bound_to_the_skin_ride_it():
    """On the body the viewer sees, a strap rides the skin nearest to it: at rest it is where it was
    modelled, under a rigid move of the body it moves rigidly, and posed it keeps its clearance from
    the face it rides (so it never sinks into the skin); the edges between attached vertices do not
    stretch where the skin under them does."""
    from hrr_garment.body.mesh_distance import nearest_on_mesh
    from hrr_garment.garment.attachment import bind_attached_to_skin
    from hrr_garment.garment.visible_surface import rest_mesh
    from hrr_garment.motion.rotations import axis_angle_to_matrix
    from tests.body.test_skinned_body import _mannequin

    mesh, skin = make_garment("dress", 600), _mannequin()
    binding = bind_attached_to_skin(mesh, skin, DEFAULT_BODY)
    rest = DEFAULT_BODY.rest_joints()[None]
    identity = np.broadcast_to(np.eye(3), (1, 22, 3, 3))
    assert np.abs(binding.pose(identity, rest)[0] - mesh.vertices[mesh.attached]).max() < 1e-6
    walk = synthesize("walk", 0.5, seed=3)
    turn, shift = axis_angle_to_matrix(np.array([0.0, 0.7, 0.0])), np.array([1.0, 0.0, -2.0])
    moved = binding.pose(turn @ walk.global_rotations, walk.joint_positions @ turn.T + shift)
    assert np.allclose(moved, binding.pose(walk.global_rotations, walk.joint_positions) @ turn.T + shift)
    # each pin rides its nearest face at rest: its offset is its distance from the rest skin there
    distance, _, _ = nearest_on_mesh(mesh.vertices[mesh.attached], rest_mesh(skin, DEFAULT_BODY), skin.faces)
    assert (binding.offset <= distance + 1e-9).all() and (binding.offset > 0).all()
    # posed without the relaxation, each pin is at its rest offset from its posed face's plane
    bare = replace(binding, held=binding.held[:0])
    pins = bare.pose(walk.global_rotations, walk.joint_positions)
    posed_skin = skin.pose(walk.global_rotations, walk.joint_positions)[:, skin.faces]  # (T, F, 3, 3)
    _, face, _ = nearest_on_mesh(mesh.vertices[mesh.attached], rest_mesh(skin, DEFAULT_BODY), skin.faces)
    corners = posed_skin[:, face]  # (T, A, 3, 3)
    normal = np.cross(corners[:, :, 1] - corners[:, :, 0], corners[:, :, 2] - corners[:, :, 0])
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    height = ((pins - corners[:, :, 0]) * normal).sum(-1)
    assert np.allclose(height, binding.offset[None], atol=1e-9)
    # the edges held are exactly the mesh's edges between two attached vertices, at their rest lengths
    attached = set(mesh.attached.tolist())
    among = {tuple(sorted(e)) for e in mesh.edges().tolist() if e[0] in attached and e[1] in attached}
    held = {tuple(sorted(e)) for e in mesh.attached[binding.held].tolist()}
    assert held == among and len(held) > 0
    ends = mesh.vertices[mesh.attached[binding.held]]
    assert np.allclose(binding.held_lengths, np.linalg.norm(ends[:, 0] - ends[:, 1], axis=1))

    # posed, the skin under the straps stretches them (this coarse test skin), the held edges come
    # back to within 5 % of their rest lengths
    def strain(posing) -> np.ndarray:
        ends = posing.pose(walk.global_rotations, walk.joint_positions)[:, binding.held]
        return np.linalg.norm(ends[:, :, 0] - ends[:, :, 1], axis=-1) / binding.held_lengths

    assert strain(bare).max() > 1.2
    assert strain(binding).max() < 1.05


def test_relaxing_stretch_draws_stretched_edges_back_and_leaves_the_rest():
    """A chain stretched in the middle comes back to its rest lengths within a percent, never shorter
    than them; an unstretched or compressed chain is left exactly as it was; and the result moves
    rigidly with its input."""
    from hrr_garment.garment.attachment import relax_stretch
    from hrr_garment.motion.rotations import axis_angle_to_matrix

    edges = np.array([[0, 1], [1, 2], [2, 3], [3, 4]])
    rest = np.full(4, 0.1)
    x = np.array([0.0, 0.1, 0.25, 0.35, 0.45])  # the middle edge 50 % long
    chain = np.stack([x, np.zeros(5), np.zeros(5)], -1)[None]
    relaxed = relax_stretch(chain, edges, rest, passes=100)
    lengths = np.linalg.norm(np.diff(relaxed[0], axis=0), axis=1)
    assert lengths.max() < 1.01 * 0.1 and lengths.min() > 0.1 - 1e-9
    compressed = chain * [0.5, 1.0, 1.0]
    assert np.array_equal(relax_stretch(compressed, edges, rest), compressed)
    turn, shift = axis_angle_to_matrix(np.array([0.3, 1.1, -0.4])), np.array([0.5, -1.0, 2.0])
    assert np.allclose(relax_stretch(chain @ turn.T + shift, edges, rest), relaxed @ turn.T + shift)


def test_a_nan_vertex_is_refused_and_a_triangle_is_no_garment(tmp_path, capsys):
    """Issue 88: ``v nan 1.0 0.0`` was dropped with its faces and the rest simulated; a one-triangle
    garment was simulated and trained on."""
    from hrr_garment.cli.simulate import main as simulate

    path = tmp_path / "nan.obj"
    path.write_text("v 0 0 0\nv nan 1.0 0.0\nv 1 0 0\nv 1 1 0\ng band\nf 1 2 3\nf 1 3 4\n")
    with pytest.raises(GarmentError, match="line 2: a vertex coordinate is not a finite number"):
        read_obj(path)
    triangle = tmp_path / "triangle.obj"
    triangle.write_text("v 0 1.2 0.1\nv 0.1 1.2 0.1\nv 0 1.1 0.1\ng band\nf 1 2 3\n")
    far = tmp_path / "far.obj"
    far.write_text(path.read_text().replace("nan", "1e300"))
    cases = (
        (path, "not a finite number"),
        (triangle, "a garment to simulate has at least"),
        (far, "beyond 1e+06"),
    )
    for obj, phrase in cases:
        args = f"--template {obj} --attached band --preset tiny -o {tmp_path / 'd.h5'}".split()
        assert simulate(args) == 2
        err = capsys.readouterr().err
        assert str(obj) in err and phrase in err and not (tmp_path / "d.h5").exists()
