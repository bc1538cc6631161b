"""Evaluation results: one mode's metrics per sequence (:class:`SequenceResult`) and over every
sequence (:class:`ModeResult`), combined weighted by frames (:func:`combine`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .ensemble_metrics import ensemble_ratios


@dataclass
class SequenceResult:
    """One mode's metrics on one sequence, with its per-frame error, entropy and gate."""

    name: str
    frames: int
    metrics: dict[str, float]
    per_frame_pve_mm: np.ndarray  # (T,)
    entropy: np.ndarray  # (T,) motion-code entropy of the window centred on each frame
    retrieved: np.ndarray  # (T,) bool
    ensemble: dict[str, float] = field(default_factory=dict)  # against the truth ensemble, when there is one
    # what the viewer sees of its body, which the inside_visible metrics count against
    # (:mod:`.visible_inside`: "mesh", "capsules" or "unknown")
    visible_body: str = "unknown"


@dataclass
class ModeResult:
    """One mode's results over every sequence; ``metrics`` weights them by frames."""

    mode: str
    tau: float
    sequences: list[SequenceResult] = field(default_factory=list)
    gate: str = "entropy"  # the hybrid's gate signal, which tau thresholds
    swing: float = 1.0  # the swing gain the mode ran with (inference/swing.py; auto: the calibrated one)
    settle: float = 0.0  # the settling lag it ran with (s, as the run asked; inference/settle.py)

    @property
    def metrics(self) -> dict[str, float]:
        return combine([s.metrics for s in self.sequences], [s.frames for s in self.sequences])

    @property
    def ensemble(self) -> dict[str, float]:
        """Ensemble scores over the sequences that have a truth ensemble (empty when none has)."""
        rows = [s for s in self.sequences if s.ensemble]
        if not rows:
            return {}
        combined = combine([s.ensemble for s in rows], [s.frames for s in rows])
        return {**combined, **ensemble_ratios(combined), "sequences": len(rows)}

    @property
    def visible_bodies(self) -> dict[str, int]:
        """How many sequences had each kind of visible body (:mod:`.visible_inside`)."""
        kinds = [s.visible_body for s in self.sequences]
        return {kind: kinds.count(kind) for kind in sorted(set(kinds))}

    def to_dict(self) -> dict:
        return {
            "mode": self.mode,
            "gate": self.gate,
            "tau": self.tau,
            "swing": self.swing,
            "settle": self.settle,
            "metrics": self.metrics,
            "ensemble": self.ensemble,
            "visible_bodies": self.visible_bodies,
            "sequences": {
                s.name: {
                    "frames": s.frames,
                    "visible_body": s.visible_body,
                    **s.metrics,
                    **({"ensemble": {**s.ensemble, **ensemble_ratios(s.ensemble)}} if s.ensemble else {}),
                }
                for s in self.sequences
            },
        }


MAXIMA = (
    "strain_max",
    "truth_strain_max",
    "penetration_before_worst_pct",
    "truth_penetration_worst_pct",
    "inside_visible_worst_pct",
    "inside_visible_before_worst_pct",
    "truth_inside_visible_worst_pct",
)


def combine(rows: list[dict[str, float]], weights: list[int]) -> dict[str, float]:
    """Frame-weighted means of per-sequence metrics (RMSE combined as a root mean square, the maximum
    strain as a maximum)."""
    w = np.asarray(weights, float) / max(sum(weights), 1)
    out = {}
    for key in rows[0]:
        values = np.array([r[key] for r in rows])
        if key == "rmse_mm":
            out[key] = float(np.sqrt((w * values**2).sum()))
        elif key in MAXIMA:
            out[key] = float(values.max())
        else:
            out[key] = float((w * values).sum())
    return out
