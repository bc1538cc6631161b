"""Fixtures of the inference tests: the shared tiny model loaded as an Animator."""

import pytest


@pytest.fixture(scope="module")
def animator(trained):
    from hrr_garment.inference.animator import Animator

    root, _, _ = trained
    return Animator.load(root / "model")
