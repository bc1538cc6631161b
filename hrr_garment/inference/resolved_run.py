"""A run's settings resolved against one model (:class:`ResolvedRun`): what every stage below the
API reads (:mod:`.run_settings` makes it, :meth:`~.run_settings.RunSettings.resolve`)."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from .modes import Mode

if TYPE_CHECKING:
    from ..garment.material import Material
    from .character_body import CharacterBody
    from .run_settings import DetailLook

#: old names of :meth:`ResolvedRun.record`'s keys in files written before (out.h5, report.json)
OLD_RECORD_NAMES = {"push_out": "collision"}


@dataclass(frozen=True)
class ResolvedRun:
    """Run settings resolved against one model: every value concrete (see :meth:`RunSettings.resolve`)."""

    mode: Mode  # never auto
    gate: str
    tau: float
    detail: DetailLook | None  # concrete base and strength in the detail mode, else None
    push_out: bool
    causal: bool
    decoder: str  # "full" or "fast"
    swing: float  # the gain on the free cloth's swing (inference/swing.py), 1: as predicted
    settle: float  # the settling lag's time constant (s) after a stop (inference/settle.py), 0: none
    push: str  # "mesh" or "subspace" (the push in the garment's subspace first)
    # "visible" (the mesh the viewer sees, where the body has one; else its capsules) or "capsules"
    push_body: str
    body: CharacterBody = field(hash=False)  # the body animated on, ready for the model
    exclude_sequence: int | None  # the database sequence retrieval may not use, or None
    precision: str  # the full mesh decoder's arithmetic ("float32" or "bfloat16")
    device: str | None  # where a crowd runs, as asked (None: the crowd's choice, Animator.crowd)
    seed: int = 0  # the sample mode's seed
    sample_steps: int | None = None  # the sample mode's integration steps a frame (None outside it)
    # the cloth animated (inference/run_material.py); None for a model from before cloths were recorded
    material: Material | None = None

    @property
    def fold_base(self) -> str:
        """What the detail mode's folds ride on ("regression" outside the detail mode)."""
        return self.detail.base if self.detail is not None else "regression"

    def record(self) -> dict:
        """What out.h5's attributes and report.json's settings record of the run's look (files
        before push_out had its old name, :data:`OLD_RECORD_NAMES`: :func:`recorded` reads both)."""
        out = {
            "mode": str(self.mode),
            "gate": self.gate,
            "tau": self.tau,
            "causal": int(self.causal),
            "push_out": int(self.push_out),
            "decoder": self.decoder,
            "swing": self.swing,
            "settle": self.settle,
            "push": self.push,
            "push_body": self.push_body,
        }
        if self.detail is not None:
            out.update(detail_base=self.detail.base, detail_strength=self.detail.strength)
        if self.sample_steps is not None:
            out.update(seed=self.seed, sample_steps=self.sample_steps)
        if self.material is not None:  # its name and its values, as a material file writes them
            out.update(material=json.dumps(self.material.to_dict(), sort_keys=True))
        return out


def recorded(settings: dict, name: str):
    """Setting ``name`` of a run's record (:meth:`ResolvedRun.record`), written under its name or,
    by an older version, its old one; a KeyError naming it where neither is."""
    if name in settings:
        return settings[name]
    return settings[OLD_RECORD_NAMES.get(name, name)]
