"""The autoencoder stage's training settings (``autoencoder.train``:
:class:`AutoencoderTrainSettings`) and the encoding's settings read back from a run's records
(:func:`refine_settings`)."""

from __future__ import annotations

from dataclasses import dataclass

from ..settings import from_settings


@dataclass(frozen=True)
class AutoencoderTrainSettings:
    """The autoencoder stage's training settings (configs/train.yaml, ``autoencoder.train``)."""

    epochs: int = 300
    batch_size: int = 32
    learning_rate: float = 8e-3
    lr_final: float = 0.01  # the cosine schedule's last learning rate, as a fraction of the first
    laplacian: float = 0.2
    patience: int = 30  # epochs without a better validation error before stopping (see early_stop)
    max_minutes: float | None = (
        None  # a wall-clock cap on the epochs (a run it cuts short warns: pipeline.budget)
    )
    target_mm: float | None = (
        None  # validation error these settings reach on an idle machine (a run far above it warns)
    )
    seed: int = 0
    threads: int | None = None
    device: str = "cpu"  # torch device to train on ("cuda" on a GPU machine); the outputs are the same files
    mirror: bool = True  # add left-right mirrored training frames when the template is symmetric (and the
    #                      dataset does not hold mirrored sequences already)
    frames_per_epoch: int | None = 16384  # an epoch draws at most this many training frames (None: all)
    refine_steps: int = 10  # Adam steps on each encoded latent through the decoder (0: the encoder's latents)
    refine_lr: float = 0.03

    @classmethod
    def from_dict(cls, values: dict) -> "AutoencoderTrainSettings":
        return from_settings(cls, values, "training")


def refine_settings(values: dict) -> dict:
    """The encoding's settings (``fit_latents``' steps and rate) from a train config as a dict: a
    run's own, its saved config.json, or a bundle's record. Missing ones (files from before they
    were recorded) are the defaults."""
    default = AutoencoderTrainSettings()
    return {
        "refine_steps": int(values.get("refine_steps", default.refine_steps)),
        "refine_lr": float(values.get("refine_lr", default.refine_lr)),
    }
