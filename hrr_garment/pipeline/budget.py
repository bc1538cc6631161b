"""Whether a training stage got what its settings asked for: its epochs, and the error they reach.

A budget in minutes made the model depend on the machine: on a busy 2-core machine the real-quick
autoencoder got one epoch of its 8 minutes and stopped at 8.70 mm validation where an idle one
reaches about 3 mm, and nothing said so. The presets' budgets are epochs now; ``max_minutes`` is a
cap (about three times what an idle 2-core Xeon needs), each stage's report says why it stopped
(:mod:`hrr_garment.train.schedule`), and ``target_mm`` is the validation error the settings reach on
an idle machine. After each stage :func:`check_budget` compares, and :func:`train_model
<hrr_garment.pipeline.train.train_model>` hands its warnings to the callback (hrr-train prints them;
a library caller gets a :class:`TrainingBudgetWarning` unless its callback takes them). A run the
cap cut short resumes where it stopped when re-run with a larger cap.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..train.report import StageReport
from ..train.schedule import STOPPED_BY_CAP

FAR_ABOVE_TARGET = 1.25  # a validation error this many times the target is far from what the settings reach


class TrainingBudgetWarning(UserWarning):
    """A stage ended short of its epochs or far above its target error (or, the subspace stage, its
    fast decoder far from the full one's validation error)."""


@dataclass(frozen=True)
class BudgetCheck:
    """One stage's epochs and validation error beside what its settings asked for."""

    stage: str
    epochs: int  # trained, interrupted runs included
    epochs_asked: int | None  # None: a report from before the epochs were recorded
    stopped: str | None  # train.schedule's reason; None: unknown
    cap_minutes: float | None  # the wall-clock cap the run had
    validation_mm: float | None
    target_mm: float | None

    @property
    def cut_short(self) -> bool:
        return self.stopped == STOPPED_BY_CAP

    @property
    def target_ratio(self) -> float | None:
        """The validation error over the target (None without both)."""
        if self.validation_mm is None or not self.target_mm:
            return None
        return self.validation_mm / self.target_mm

    def summary(self) -> str:
        """One line: epochs of those asked, why it stopped, the error against the target."""
        asked = f" of {self.epochs_asked}" if self.epochs_asked is not None else ""
        why = f", stopped by {self.stopped}" if self.stopped else ""
        ratio = self.target_ratio
        target = (
            f"; validation {self.validation_mm:.2f} mm against a target of {self.target_mm:.2f} mm "
            f"({ratio:.2f} x)"
            if ratio is not None
            else ""
        )
        return f"{self.stage}: {self.epochs}{asked} epochs{why}{target}"

    def warnings(self) -> list[str]:
        out = []
        if self.cut_short:
            out.append(
                f"{self.stage}: its {self.cap_minutes:g}-minute cap stopped training after {self.epochs} of "
                f"{self.epochs_asked} epochs (a busy or slow machine): the model is weaker than these "
                "settings make. Re-run the same command with a larger max_minutes (--config; --minutes for "
                "the autoencoder) to finish the epochs from where it stopped"
            )
        ratio = self.target_ratio
        if ratio is not None and ratio > FAR_ABOVE_TARGET:
            out.append(
                f"{self.stage}: validation error {self.validation_mm:.2f} mm is {ratio:.2f} x the "
                f"{self.target_mm:.2f} mm these settings reach on an idle machine"
            )
        return out


def check_budget(report: StageReport, train_config) -> BudgetCheck:
    """``report`` against the stage's training config (``max_minutes``, ``target_mm``)."""
    return BudgetCheck(
        report.stage,
        report.epochs,
        report.epochs_asked,
        report.stopped,
        getattr(train_config, "max_minutes", None),
        report.validation_mm,
        getattr(train_config, "target_mm", None),
    )
