"""An animated garment (:class:`Animation`): what :meth:`~.animator.Animator.animate` returns,
its check against absurd results and its out.h5."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..body.body_file import BodyRecord, body_to_dict
from ..body.mannequin import MANNEQUIN
from ..data.animation_file import MAX_REACH_M, farthest_from_body
from ..errors import InputError
from ..garment.material import Material, recorded_material
from ..io_utils import strict_json
from ..motion.motion import Motion
from ..motion.rotations import matrix_to_quat
from .collision import PushOutReport


@dataclass
class Animation:
    """An animated garment: world-space vertices (T, V, 3) at ``fps``, Y up, metres, and what made
    each frame (``settings``: the run as :meth:`~.run_settings.ResolvedRun.record` gives it)."""

    vertices: np.ndarray
    faces: np.ndarray
    fps: float
    retrieved: (
        np.ndarray
    )  # (T,) uint8, 1 = the frame's window is a database window as simulated (never in residual/detail)
    entropy: np.ndarray  # (T,) float32 motion-code entropy
    match: (
        np.ndarray
    )  # (T, 2) int32 the database window (sequence, start frame) that gave or lent to the frame, or -1
    joints: np.ndarray  # (T, 22, 3) body joint positions
    garment: str
    model_hash: str
    motion_file: str  # where the motion came from (its file, or a description)
    settings: dict = field(default_factory=dict)
    penetration: PushOutReport | None = None
    capsules: np.ndarray | None = None  # (T, C, 2, 3) collision capsule ends, for previews and exports
    radii: np.ndarray | None = None  # (C,) the capsules' radii
    body_name: str = MANNEQUIN  # the name of the body it was animated on
    skeleton: Motion | None = (
        None  # the motion as the body played it (its skeleton and rotations), for exports
    )
    body_record: BodyRecord | None = None  # the body itself (previews draw its own mesh where it has a shape)
    doubt: np.ndarray | None = None  # (T,) the gate signal's value per frame (retrieval where below tau)

    @property
    def material(self) -> Material | None:
        """The cloth animated (the run's, :mod:`.run_material`); None for a model from before cloths
        were recorded."""
        return recorded_material(self.settings.get("material"), "the animation")

    @property
    def retrieval_usage(self) -> float:
        """The fraction of frames whose window was retrieved from the database."""
        return float(self.retrieved.mean()) if len(self.retrieved) else 0.0

    def check(self, target: str | Path) -> None:
        """Refuse to hand on an absurd result: non-finite vertices or joints, or a garment vertex
        farther than ``MAX_REACH_M`` from every joint (a damaged or mismatched model, not cloth)."""
        for name, values in (("vertices", self.vertices), ("joints", self.joints)):
            bad = ~np.isfinite(values.reshape(len(values), -1)).all(1)
            if bad.any():
                raise InputError(
                    target,
                    f"the model produced non-finite {name} on {int(bad.sum())} frame(s), first at "
                    f"frame {int(np.argmax(bad))}; nothing written (is the model bundle damaged?)",
                )
        reach, frame = farthest_from_body(self.vertices, self.joints)
        if frame >= 0:
            raise InputError(
                target,
                f"the model put a garment vertex {reach:.2f} m from the body at frame {frame} "
                f"(more than {MAX_REACH_M:g} m); nothing written (a damaged or mismatched model?)",
            )

    def save(self, path: str | Path) -> Path:
        """Write ``out.h5`` (see :mod:`hrr_garment.data.animation_file`), atomically, after :meth:`check`."""
        from ..data.animation_file import AnimationArrays, write_animation_h5

        self.check(path)
        played = {}
        if self.skeleton is not None:
            played = {
                "rotations": matrix_to_quat(self.skeleton.local_rotations)[..., [1, 2, 3, 0]],  # (x, y, z, w)
                "root_translation": self.skeleton.root_translation,
                "offsets": self.skeleton.skeleton.offsets,
            }
        arrays = AnimationArrays(
            vertices=self.vertices,
            faces=self.faces,
            joints=self.joints,
            retrieved=self.retrieved,
            entropy=self.entropy,
            match=self.match,
            capsules=self.capsules,
            radii=None if self.capsules is None else self.radii,
            **played,
        )
        return write_animation_h5(
            path,
            arrays,
            {
                "fps": self.fps,
                "garment": self.garment,
                "source_motion": self.motion_file,
                "model_hash": self.model_hash,
                "body_name": self.body_name,
                "body_record": None
                if self.body_record is None
                else strict_json(body_to_dict(self.body_record)),
                **self.settings,
            },
        )
