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
    """Sequences whose garment swings with the body's speed and turning (in its heading frame), so
    garment windows follow from motion windows; no simulator needed."""
    from hrr_garment.data.dataset import SequenceRecord, write_dataset
    from hrr_garment.motion.features import motion_features
    from hrr_garment.motion.rotations import rotation_about_y, yaw_of
    from hrr_garment.motion.synth import synthesize

    v = garment.vertices.astype(np.float32)
    depth = np.clip((v[:, 1].max() - v[:, 1]) / np.ptp(v[:, 1]), 0, 1)[None, :] ** 2
    records = []
    for name, kind, seed in (("walk_000", "walk", 0), ("walk_001", "walk", 1), ("spin_000", "spin", 0),
                             ("walk_002", "walk", 2), ("run_000", "run", 0)):
        motion = synthesize(kind, 1.5, seed=seed)
        f = motion_features(motion)
        speed, turn = np.tanh(f[:, -4:-1].sum(1, keepdims=True)), np.tanh(f[:, -1:])
        local = np.repeat(v[None], motion.num_frames, 0)
        local[..., 2] -= 0.1 * depth * speed
        local[..., 0] += 0.1 * depth * turn
        yaw = yaw_of(motion.global_rotations[:, 0])
        world = np.einsum("tij,tnj->tni", rotation_about_y(yaw), local) + (motion.root_translation * [1, 0, 1])[:, None]
        records.append(SequenceRecord(name, world.astype(np.float32), motion))
    splits = {"train": ["walk_000", "walk_001", "spin_000"], "val": ["walk_002"], "test": ["run_000"]}
    return write_dataset(path, garment, records, splits)


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
