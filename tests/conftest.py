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


def synthetic_dataset(path, garment):
    """The simulator-free dataset (hrr_garment.data.synthetic): its garment follows the motion."""
    from hrr_garment.data.synthetic import write_synthetic_dataset

    return write_synthetic_dataset(path, garment)


TINY_TRAINING = """
autoencoder:
  model: {channels: [8, 16]}
  train: {epochs: 3, batch_size: 16, max_minutes: null}
codespace:
  model: {groups: 16, classes: 4, embedding_dim: 4, hidden: 64, motion_hidden: 32, attention_heads: 2}
  train: {epochs: 4, learning_rate: 0.001, plateau_patience: 2, patience: 5, max_minutes: null}
"""


@pytest.fixture(scope="session")
def trained(tmp_path_factory):
    from hrr_garment.cli.train import main as train_main
    from hrr_garment.garment.templates import make_garment

    root = tmp_path_factory.mktemp("codespace")
    data = synthetic_dataset(root / "skirt.h5", make_garment("skirt", 300))
    (root / "cfg.yaml").write_text(TINY_TRAINING)
    args = ["--dataset", str(data), "--config", str(root / "cfg.yaml"), "-o", str(root / "model"), "--quiet"]
    assert train_main(args) == 0
    return root, data, args
