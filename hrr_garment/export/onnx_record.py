"""What an exported step's graph carries beside its nodes (docs/export.md): its metadata (what it
animates and how, its state's shapes, the sample mode's noise, a model across cloths' material
input, the terms of its motion) and its companion npz (:data:`TENSORS`: what ONNX cannot hold, the
retrieval database, with the garment's faces), written by :func:`~.onnx_model.export_onnx`."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .._version import __version__
from ..garment.material_range import MATERIAL_FEATURES
from ..io_utils import atomic_path, strict_json
from ..motion.motion import FPS
from ..motion.skeleton import JOINT_NAMES

# what the companion npz holds (docs/export.md says how a retrieval uses them)
TENSORS = {
    "faces": "(F, 3) int32 the garment's triangles",
    "joint_names": "(22,) the joints of the rotations input, in order",
    "database_codes": "(M, G) uint8 each database window's motion code (one class of K per group)",
    "database_latents": "(M, nodes, C) float32 the simulated garment latents of each window's last frame",
    "database_sequence": "(M,) int32 the simulated sequence each window comes from",
    "database_start": "(M,) int32 its first frame in that sequence",
}


def tensors_path(graph: str | Path) -> Path:
    """The companion file of the graph ``graph``: ``<stem>.tensors.npz`` beside it."""
    graph = Path(graph)
    return graph.with_name(f"{graph.stem}.tensors.npz")


def graph_metadata(bundle, run, *, shapes: dict, noise, cloth) -> dict:
    """The graph's metadata (docs/export.md): what it animates and how, its state's shapes, the
    sample mode's noise, a model across cloths' material input, and the terms of its motion."""
    meta = {
        "hrr_garment": __version__,
        "garment": bundle.garment,
        "content_hash": bundle.content_hash,
        "fps": FPS,
        "push_out": bool(run.push_out),
        "push": run.push,
        "push_body": run.push_body,
        "body": run.body.name,
        "decoder": run.decoder,
        "vertices": int(bundle.template.num_vertices),
        "state": {k: list(v) for k, v in shapes.items()},
        "path": run.mode.value,
        # the graph holds the database's simulated windows and weights learned from the motion: its
        # terms travel with it (motion/licences.py)
        "motion_licence": bundle.manifest.licences.statement,
        "commercial_use": bundle.manifest.licences.commercial,
    }
    if run.settle > 0:  # the settling lag the graph runs (its state ``settled``)
        meta["settle"] = run.settle
    if noise is not None:  # the white noise a frame takes per character, and the steps it is drawn in
        meta |= {"noise": list(noise), "sample_steps": run.sample_steps}
    if cloth is not None:  # the material input: what it holds and the cloth exported with
        meta |= {
            "material": list(MATERIAL_FEATURES),
            "material_default": run.material.to_dict(),
            "material_range": bundle.material_range.to_dict(),
        }
    return meta


def write_tensors(tensors: Path, bundle) -> None:
    """The graph's companion (atomically): the garment's faces, the joints' order and the database's
    codes and latents, for a retrieval of an engine's own."""
    db = bundle.database
    with atomic_path(tensors) as tmp, open(tmp, "wb") as fh:
        np.savez(
            fh,
            faces=bundle.template.faces.astype(np.int32),
            joint_names=np.array(JOINT_NAMES),
            database_codes=np.asarray(db.codes, np.uint8),
            database_latents=np.asarray(db.latents[np.arange(len(db)), -1], np.float32),
            database_sequence=np.asarray(db.sequence, np.int32),
            database_start=np.asarray(db.start, np.int32),
        )


def record_metadata(model, meta: dict) -> None:
    """``meta`` into the ONNX ``model``'s metadata properties, a value not a string as JSON."""
    for key, value in meta.items():
        entry = model.metadata_props.add()
        entry.key, entry.value = key, value if isinstance(value, str) else strict_json(value)
