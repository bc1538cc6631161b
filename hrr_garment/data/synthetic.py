"""A small dataset made without the simulator, for tests and tools (fuzzing, smoke runs).

The garment swings with the body's speed and turning, in the body's heading frame, so that its
windows follow from the motion's windows as a simulated garment's would: a model trained on it
has something real to learn, in seconds. It is not physics and is never used to report fidelity.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..body.mannequin import MANNEQUIN
from ..body.retarget import motion_on_body
from ..garment.dressing import DressedBody
from ..garment.fabrics import FABRICS
from ..garment.material import Material
from ..garment.mesh import GarmentMesh
from ..motion.features import motion_features
from ..motion.licences import PROCEDURAL, SOURCES
from ..motion.rotations import rotation_about_y, yaw_of
from ..motion.synth import synthesize
from .dataset import SequenceRecord, write_dataset

# (sequence name, procedural kind, seed): three training clips, one for validation, one for test
SEQUENCES = (
    ("walk_000", "walk", 0),
    ("walk_001", "walk", 1),
    ("spin_000", "spin", 0),
    ("walk_002", "walk", 2),
    ("run_000", "run", 0),
)
SPLITS = {"train": ["walk_000", "walk_001", "spin_000"], "val": ["walk_002"], "test": ["run_000"]}


def cloth_swing(material: Material) -> float:
    """How far a cloth swings here, relative to the default cloth's: as (density / bend)^(1/4), so
    that a lighter, softer cloth swings farther (a fold's length goes with (bend / density)^(1/3))."""
    default = FABRICS["default"]
    return float((material.density / material.bend / (default.density / default.bend)) ** 0.25)


def write_synthetic_dataset(
    path: str | Path,
    garment: GarmentMesh,
    seconds: float = 1.5,
    bodies: list[DressedBody] | None = None,
    materials: list[Material] | None = None,
) -> Path:
    """Write the five sequences of ``garment`` to ``path`` (an .h5 dataset); returns the path.
    ``bodies``: the sequences in turn on each of these bodies (:class:`~.bodies.DressedBody`, the
    garment on it), each played by its body, the garment hanging from the body's own rest shape
    and swinging with the speed of the body's own stride; default the mannequin. ``materials``: the
    sequences in turn in each of these cloths, recorded as a simulation records them, each swinging
    by :func:`cloth_swing`; default none recorded (the default cloth)."""
    records = []
    for i, (name, kind, seed) in enumerate(SEQUENCES):
        motion, rest, body_name = synthesize(kind, seconds, seed=seed), garment.vertices, MANNEQUIN
        if bodies:
            dressed = bodies[i % len(bodies)]
            motion, rest, body_name = (
                motion_on_body(motion, dressed.record),
                dressed.garment.vertices,
                dressed.name,
            )
        v = rest.astype(np.float32)
        # how far down the garment a vertex hangs, 0 at the waist to 1 at the hem, squared: hems swing most
        depth = np.clip((v[:, 1].max() - v[:, 1]) / np.ptp(v[:, 1]), 0, 1)[None, :] ** 2
        f = motion_features(motion)
        speed, turn = np.tanh(f[:, -4:-1].sum(1, keepdims=True)), np.tanh(f[:, -1:])
        local = np.repeat(v[None], motion.num_frames, 0)
        cloth = materials[i % len(materials)] if materials else None
        swing = 0.1 * (cloth_swing(cloth) if cloth is not None else 1.0)
        local[..., 2] -= swing * depth * speed
        local[..., 0] += swing * depth * turn
        yaw = yaw_of(motion.global_rotations[:, 0])
        world = (
            np.einsum("tij,tnj->tni", rotation_about_y(yaw), local)
            + (motion.root_translation * [1, 0, 1])[:, None]
        )
        info = {} if cloth is None else {"material": cloth.to_dict()}
        records.append(SequenceRecord(name, world.astype(np.float32), motion, info=info, body_name=body_name))
    sources = {
        "motion_sources": {r.name: PROCEDURAL for r in records},
        "sources": {PROCEDURAL: SOURCES[PROCEDURAL].to_dict()},
    }
    return write_dataset(
        path, garment, records, splits=SPLITS, info=sources, bodies={b.name: b for b in bodies or []}
    )
