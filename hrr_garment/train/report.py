"""What every training stage returns: :class:`StageReport`, one dataclass for all of them."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path


@dataclass
class StageReport:
    """A finished (or reused) training stage.

    The fields every stage has are typed; ``metrics`` holds the stage's own numbers, as its
    ``report.json`` records them (the autoencoder's per-vertex errors, the code space's validation
    errors and database statistics, the baseline's validation error).
    """

    stage: str  # "autoencoder", "codespace", "subspace" or "direct"
    folder: Path  # where the stage's outputs are
    epochs: int  # epochs trained, interrupted runs included
    best_epoch: int  # the epoch whose weights were kept
    minutes: float  # wall time of the run that made the outputs
    reused: bool = False  # the outputs were current: nothing was trained or written
    metrics: dict = field(default_factory=dict)
    epochs_asked: int | None = (
        None  # the epochs its settings asked for (None: a report from before they were kept)
    )
    stopped: str | None = (
        None  # why training stopped (train.schedule: "epochs", "early stop", "minutes cap"); None: unknown
    )
    validation_mm: float | None = None  # the validation error its settings' ``target_mm`` is compared with

    @classmethod
    def of_record(
        cls, stage: str, folder: Path, record: dict, *, reused: bool = False, **fields
    ) -> "StageReport":
        """The report of a stage's record (its report.json or bundle.json entry, just written or read
        back to reuse): the epochs, best epoch and minutes it holds; ``fields``, the others
        (``metrics``, the record itself unless given)."""
        return cls(
            stage,
            folder,
            int(record["epochs"]),
            best_epoch=int(record["best_epoch"]),
            minutes=float(record["minutes"]),
            reused=reused,
            **({"metrics": record} | fields),
        )
