"""A dataset's frames as the models learn them (:func:`body_frames`: in each frame's body frame,
less the rest offset of the body it was simulated on) and the autoencoder's training frames per
split, the training split with its left-right mirror (:func:`training_frames`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..data.dataset import GarmentDataset
from ..garment.mesh import mirror_map
from ..motion.frame import to_body_frame


@dataclass
class TrainingFrames:
    """A dataset's frames in the body frame, per split; ``train`` ends with the mirrored copies."""

    train: np.ndarray  # (N, V, 3) float32
    val: np.ndarray
    test: np.ndarray
    simulated: int  # the training frames before the mirrored ones
    scale: float  # the offsets' standard deviation from the template (the model's input scale)


def body_frames(ds: GarmentDataset, names: list[str]) -> np.ndarray:
    """All frames of ``names`` as the models learn them, (N, V, 3) float32: in each frame's body
    frame (:mod:`..motion.frame`), less the rest offset of the body the sequence was simulated on
    (:meth:`~hrr_garment.garment.dressing.DressedBody.offset`: nothing on the mannequin). A garment's
    motion relative to its own body at rest carries over between bodies; its absolute position
    does not (a 1.95 m body's dress hangs 19 cm higher in the body frame than the mannequin's)."""
    out = []
    for name in names:
        rec = ds.sequence(name)
        frames = to_body_frame(rec.garment.astype(np.float64), rec.motion).astype(np.float32)
        out.append(frames - ds.bodies[ds.body_name_of[name]].offset(ds.template))
    return np.concatenate(out) if out else np.zeros((0, ds.template.num_vertices, 3), np.float32)


def holds_mirrors(ds: GarmentDataset) -> bool:
    """Whether the dataset was built with every sequence mirrored (``hrr-simulate`` with a preset's
    ``mirror: true``): then mirroring its frames again only doubles them."""
    return bool(ds.info.get("augmentation", {}).get("mirror"))


def training_frames(ds: GarmentDataset, mirror: bool) -> TrainingFrames:
    """Every split's frames, the training split with its left-right mirror when asked, the
    template is symmetric and the dataset does not hold the mirrored sequences already."""
    splits = ds.splits
    train = body_frames(ds, splits["train"])
    val = body_frames(ds, splits.get("val", []))
    test = body_frames(ds, splits.get("test", []))
    template = ds.template.vertices.astype(np.float32)
    perm = mirror_map(template) if mirror and not holds_mirrors(ds) else None
    simulated = len(train)
    if perm is not None:  # body frame: x is the body's left-right axis
        train = np.concatenate([train, train[:, perm] * np.array([-1, 1, 1], np.float32)])
    scale = float(np.std(train - template)) if len(train) else 0.1
    return TrainingFrames(train, val, test, simulated, scale)
