import numpy as np
import pytest
import torch

from hrr_garment.motion import rotations as R


def random_aa(rng, n=500):
    axis = rng.normal(size=(n, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    angle = rng.uniform(0, np.pi - 1e-3, size=(n, 1))
    if n >= 5:
        angle[:5] = [[0.0], [1e-7], [1e-5], [np.pi - 1e-4], [3e-3]]
    return axis * angle


BACKENDS = [pytest.param(lambda a: a, id="numpy"), pytest.param(lambda a: torch.from_numpy(a), id="torch")]


def as_np(x):
    return x.numpy() if isinstance(x, torch.Tensor) else x


@pytest.mark.parametrize("wrap", BACKENDS)
@pytest.mark.parametrize(
    "forward,backward",
    [
        (R.axis_angle_to_matrix, R.matrix_to_axis_angle),
        (R.axis_angle_to_quat, R.quat_to_axis_angle),
        (
            lambda aa: R.matrix_to_6d(R.axis_angle_to_matrix(aa)),
            lambda d6: R.matrix_to_axis_angle(R.sixd_to_matrix(d6)),
        ),
        (
            lambda aa: R.matrix_to_quat(R.axis_angle_to_matrix(aa)),
            lambda q: R.matrix_to_axis_angle(R.quat_to_matrix(q)),
        ),
    ],
    ids=["matrix", "quat", "6d", "quat-matrix"],
)
def test_round_trips(rng, wrap, forward, backward):
    aa = random_aa(rng)
    back = as_np(backward(forward(wrap(aa))))
    np.testing.assert_allclose(back, aa, atol=1e-6)


@pytest.mark.parametrize("wrap", BACKENDS)
def test_matrices_are_rotations_and_known_answer(rng, wrap):
    m = as_np(R.axis_angle_to_matrix(wrap(random_aa(rng))))
    np.testing.assert_allclose(m @ np.swapaxes(m, 1, 2), np.broadcast_to(np.eye(3), m.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(m), 1.0, atol=1e-12)
    quarter_z = as_np(R.axis_angle_to_matrix(wrap(np.array([0.0, 0.0, np.pi / 2]))))
    np.testing.assert_allclose(quarter_z @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-12)


def test_numpy_and_torch_agree(rng):
    aa = random_aa(rng)
    for f in (R.axis_angle_to_matrix, R.axis_angle_to_quat):
        np.testing.assert_allclose(f(aa), f(torch.from_numpy(aa)).numpy(), atol=1e-12)
    m = R.axis_angle_to_matrix(aa)
    np.testing.assert_allclose(R.matrix_to_quat(m), R.matrix_to_quat(torch.from_numpy(m)).numpy(), atol=1e-12)


def test_torch_gradients_are_finite(rng):
    aa = torch.tensor(random_aa(rng, 50), requires_grad=True)
    R.matrix_to_6d(R.axis_angle_to_matrix(aa)).sum().backward()
    assert torch.isfinite(aa.grad).all()


def test_quat_mul_matches_matrix_product(rng):
    a, b = random_aa(rng, 100), random_aa(rng, 100)
    qa, qb = R.axis_angle_to_quat(a), R.axis_angle_to_quat(b)
    np.testing.assert_allclose(
        R.quat_to_matrix(R.quat_mul(qa, qb)),
        R.axis_angle_to_matrix(a) @ R.axis_angle_to_matrix(b),
        atol=1e-12,
    )


def test_slerp_halfway_is_half_angle():
    q0 = R.axis_angle_to_quat(np.zeros(3))
    q1 = R.axis_angle_to_quat(np.array([0.0, 1.2, 0.0]))
    np.testing.assert_allclose(R.quat_to_axis_angle(R.quat_slerp(q0, q1, 0.5)), [0.0, 0.6, 0.0], atol=1e-12)


@pytest.mark.parametrize("order", ["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"])
def test_euler_round_trip(rng, order):
    m = R.axis_angle_to_matrix(random_aa(rng, 200)[10:])
    np.testing.assert_allclose(R.euler_to_matrix(R.matrix_to_euler(m, order), order), m, atol=1e-10)
    # BVH order "ZYX" means R = Rz @ Ry @ Rx.
    angles = np.array([10.0, 20.0, 30.0])
    single = [
        R.euler_to_matrix(np.array([a if k == i else 0.0 for k in range(3)]), order)
        for i, a in enumerate(angles)
    ]
    np.testing.assert_allclose(
        R.euler_to_matrix(angles, order), single[0] @ single[1] @ single[2], atol=1e-12
    )


def test_kabsch_and_rotation_between(rng):
    m = R.axis_angle_to_matrix(random_aa(rng, 1))[0]
    pts = rng.normal(size=(6, 3))
    np.testing.assert_allclose(R.kabsch(pts, pts @ m.T), m, atol=1e-10)
    a, b = rng.normal(size=(50, 3)), rng.normal(size=(50, 3))
    rb = R.rotation_between(a, b)
    np.testing.assert_allclose(R.normalize(np.einsum("nij,nj->ni", rb, a)), R.normalize(b), atol=1e-10)
    flip = R.rotation_between(np.array([1.0, 0, 0]), np.array([-1.0, 0, 0]))
    np.testing.assert_allclose(flip @ [1.0, 0, 0], [-1.0, 0, 0], atol=1e-12)
