"""The detail mode: the regression's shape plus the high spatial frequencies of the retrieved
window (its folds), split by the mesh's 1-ring mean."""

import numpy as np
import pytest

from hrr_garment.garment.templates import make_garment
from hrr_garment.inference.collision import mean_operator
from hrr_garment.inference.detail import add_detail
from hrr_garment.motion.synth import synthesize


@pytest.fixture(scope="module")
def skirt():
    garment = make_garment("skirt", 300)
    return garment, mean_operator(garment.faces, garment.num_vertices)


def test_detail_takes_the_folds_and_leaves_the_shape(skirt, rng):
    garment, mean = skirt
    regression = np.repeat(garment.vertices[None], 2, 0).astype(np.float32)
    # a retrieval displaced as a whole (low frequency) adds nothing: the high-pass removes constants
    assert np.allclose(add_detail(regression, regression + [0.05, -0.02, 0.01], mean), regression, atol=1e-6)
    # per-vertex noise (the highest frequency) mostly passes ...
    folds = rng.normal(0.0, 0.003, regression.shape)
    out = add_detail(regression, regression + folds, mean)
    kept = np.sum((out - regression) * folds) / np.sum(folds * folds)
    assert 0.6 < kept < 1.1
    # ... strength scales it linearly, 0 is the regression
    assert np.allclose(add_detail(regression, regression + folds, mean, strength=0.5) - regression,
                       0.5 * (out - regression), atol=1e-6)
    assert np.array_equal(add_detail(regression, regression + folds, mean, strength=0.0), regression)


def test_detail_commutes_with_a_rigid_motion(skirt, rng):
    """So it can run in the body frame and equal the same done in the world."""
    garment, mean = skirt
    a = garment.vertices[None].astype(np.float64) + rng.normal(0, 0.01, (1, garment.num_vertices, 3))
    b = a + rng.normal(0, 0.01, a.shape)
    c, s = np.cos(0.7), np.sin(0.7)
    rot = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    moved = add_detail(a @ rot.T + [1.0, 0.0, 2.0], b @ rot.T + [1.0, 0.0, 2.0], mean)
    assert np.allclose(moved, add_detail(a, b, mean).astype(np.float64) @ rot.T + [1.0, 0.0, 2.0], atol=1e-5)


def test_the_detail_mode_is_the_regression_plus_the_retrievals_folds(trained):
    from hrr_garment.inference.animator import Animator

    root, _, _ = trained
    animator = Animator.load(root / "model")
    motion = synthesize("walk", 1.0, seed=3)
    regression = animator.animate(motion, mode="regression", collision=False).vertices
    retrieval = animator.animate(motion, mode="retrieval", collision=False)
    detail = animator.animate(motion, mode="detail", collision=False)
    assert np.allclose(detail.vertices, add_detail(regression, retrieval.vertices, animator.smoothing), atol=1e-4)
    assert detail.mode.all() and np.array_equal(detail.source, retrieval.source)
    assert not np.allclose(detail.vertices, regression, atol=1e-3)
