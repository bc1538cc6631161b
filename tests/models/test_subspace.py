"""The fast decoder's parts: principal components against a planted subspace, truncation as a
prefix of the coefficients, and the choice of its size."""

import numpy as np
import pytest
import torch

from hrr_garment.models.subspace import SubspaceDecoder, SubspaceSettings, principal_components
from hrr_garment.settings import SettingsError
from hrr_garment.train.subspace_size import pick_components, subspace_warning


def test_principal_components_recover_a_planted_subspace(rng):
    directions = np.linalg.qr(rng.normal(size=(30, 3)))[0].T  # three orthonormal directions in 3V = 30
    spreads = np.array([5.0, 2.0, 0.5])
    coefficients = rng.normal(size=(4000, 3)) * spreads
    offset = rng.normal(size=30)
    frames = (offset + coefficients @ directions + 1e-4 * rng.normal(size=(4000, 30))).reshape(4000, 10, 3)
    mean, basis, spread = principal_components(frames.astype(np.float32), 3, chunk=512)
    assert np.allclose(mean, offset, atol=0.25)
    assert np.allclose(basis @ basis.T, np.eye(3), atol=1e-5)  # orthonormal rows
    assert np.abs(directions - (directions @ basis.T) @ basis).max() < 1e-4  # they span the planted subspace
    assert (np.abs(np.diag(basis @ directions.T)) > 0.99).all()  # one by one, by decreasing spread
    assert np.allclose(spread, spreads, rtol=0.05)


def test_a_truncated_decoder_is_the_prefix_of_the_coefficients(rng):
    torch.manual_seed(0)
    model = SubspaceDecoder((4, 2), 10, 6, SubspaceSettings(max_components=6, hidden=16, layers=1))
    model.basis.copy_(torch.from_numpy(np.linalg.qr(rng.normal(size=(30, 6)))[0].T.astype(np.float32)))
    model.coeff_std.copy_(torch.tensor([3.0, 2.0, 1.0, 0.5, 0.2, 0.1]))
    model.mean.copy_(torch.from_numpy(rng.normal(size=30).astype(np.float32)))
    model.eval()
    z = torch.from_numpy(rng.normal(size=(5, 4, 2)).astype(np.float32))
    c = model.coefficients(z).detach()
    c[:, 4:] = 0.0
    expected = model.vertices(c).detach()
    assert torch.allclose(model.truncated(4)(z), expected, atol=1e-5)
    assert torch.allclose(model.vertices(c[:, :4]), expected, atol=1e-5)  # a prefix of the coefficients alone
    assert model(z).shape == (5, 10, 3)
    with pytest.raises(ValueError, match="1..6"):
        model.truncated(7)


def test_the_size_is_the_fewest_components_within_the_tolerance():
    errors = {16: 4.0, 32: 3.4, 64: 3.2, 128: 3.15}
    assert pick_components(errors, full_mm=3.0, tolerance=1.1) == 64  # 3.4 > 3.3; 3.2 is the first within
    assert pick_components(errors, full_mm=3.0, tolerance=1.2) == 32  # 4.0 > 3.6
    assert pick_components(errors, full_mm=2.0, tolerance=1.1) == 128  # none within: the most accurate ...
    assert (
        pick_components({**errors, 256: 3.14}, full_mm=2.0, tolerance=1.1) == 128
    )  # ... or the fewest within 1 % of it


def test_bad_sizes_are_refused():
    with pytest.raises(SettingsError, match="hidden"):
        SubspaceSettings(hidden=0)
    with pytest.raises(SettingsError, match="components"):
        SubspaceDecoder((4, 2), 10, 31)


def test_a_fast_decoder_far_from_the_full_one_is_warned_about():
    assert subspace_warning({"validation_mm": 3.47, "full_validation_mm": 3.01}) is None
    text = subspace_warning({"validation_mm": 22.75, "full_validation_mm": 6.56})
    assert "3.5 x" in text and "decoder='full'" in text


def test_weights_loaded_after_a_forward_are_the_ones_it_decodes_with():
    torch.manual_seed(1)
    model = SubspaceDecoder((4, 2), 10, 6, SubspaceSettings(max_components=6, hidden=8, layers=1)).eval()
    z = torch.randn(3, 4, 2)
    model(z)  # the scaled basis made once
    state = {k: v.clone() for k, v in model.state_dict().items()}
    state["basis"], state["coeff_std"] = torch.randn(6, 30), state["coeff_std"] * 2.0
    model.load_state_dict(state)
    assert torch.allclose(model(z), model.vertices(model.coefficients(z)), atol=1e-5)
