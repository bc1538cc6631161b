from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hrr_garment.paths import find_mocap_dir

CMU_CLIPS = ("02_01", "131_01", "131_03")


@pytest.fixture(scope="session")
def mocap_dir() -> Path:
    found = find_mocap_dir()
    if found is None:
        pytest.skip("shared/data/mocap not found (set HRR_MOCAP_DIR)")
    return found


@pytest.fixture(scope="session")
def cmu_motions(mocap_dir):
    from hrr_garment import load_motion

    return {name: load_motion(mocap_dir / "cmu" / f"{name}.bvh") for name in CMU_CLIPS}


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(1234)
