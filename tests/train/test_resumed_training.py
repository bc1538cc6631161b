"""A training stopped as Ctrl-C stops it and run again ends with the model one uninterrupted training
gives: the code space stopped after its second of four epochs and resumed from its checkpoint (torch's
RNG, the optimizer and the schedule restored) against the same training run through, both measured
against the spread of two trainings that differ only in their seed."""

import shutil

import pytest
import torch

from hrr_garment.train import checkpoint
from tests.conftest import train_tiny

pytestmark = pytest.mark.slow


def _weights(folder) -> dict[str, torch.Tensor]:
    saved = torch.load(folder / "codebook" / "checkpoint.pt", map_location="cpu", weights_only=True)
    return {k: v.float() for k, v in saved["best_weights"].items()}


def _apart(a: dict, b: dict) -> float:
    return max(float((a[k] - b[k]).abs().max()) for k in a)


def test_a_stopped_code_space_ends_as_one_training_would(trained, tmp_path, monkeypatch):
    root, data, _ = trained
    config = root / "cfg.yaml"

    def train(name: str, seed: int = 0):
        folder = tmp_path / name
        if not folder.exists():  # the shared autoencoder, so that only the code space trains
            shutil.copytree(root / "model" / "autoencoder", folder / "autoencoder")
        overrides = {"codespace": {"train": {"seed": seed}}}
        train_tiny(data, folder, config, stages=("autoencoder", "codespace"), overrides=overrides)
        return _weights(folder)

    whole = train("whole")
    other_seed = train("other", seed=1)
    save = checkpoint.save_checkpoint

    def save_then_stop(path, key, state, *args, **kwargs):
        save(path, key, state, *args, **kwargs)
        if state["epoch"] == 2 and "codebook" in path.parts:
            raise KeyboardInterrupt

    with monkeypatch.context() as patch, pytest.raises(KeyboardInterrupt):
        patch.setattr(checkpoint, "save_checkpoint", save_then_stop)
        train("stopped")
    resumed = train("stopped")
    spread = _apart(whole, other_seed)
    assert spread > 1e-3  # two seeds train apart ...
    # ... and the stopped run ends where the uninterrupted one does, to float rounding
    assert _apart(resumed, whole) < 1e-3 * spread
