"""One epoch loop for every training stage (the autoencoder, the code space, the fast decoder, the
baseline), kept apart from the models in the manner of Lightning's ``Trainer.fit``.

A stage gives its epoch as an :class:`EpochStep` (its training batches, then its validation score)
and :func:`fit` does the rest: it resumes, counts the epochs, asks the :class:`Budget` whether
another one is due, keeps the best validation epoch's weights, and hands every finished epoch to
its callbacks (:class:`~.checkpoint.Checkpoint`, :class:`~.checkpoint.EpochLog`,
:class:`ProgressBar`). At the end the best weights are back in the model, in eval mode.

The order is fixed, since a run killed and re-run must go on exactly as one that was not: the
callbacks resume (the checkpoint restores the state, then each callback hears where the run goes
on from), then the step starts, then each epoch: the step's epoch, its number counted with the time
spent, keep-if-best, then the callbacks in the order given (the epoch's log line, then the
checkpoint with the RNG state, then the progress bar: a kill between the log line and the
checkpoint leaves a line that the resumed run drops and writes again, never a lost one).
"""

from __future__ import annotations

import math
import time
from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import dataclass, field

import torch
from tqdm.auto import tqdm

from .schedule import run_progress, stop_reason

ENDLESS_EPOCHS = 10_000  # a budget of this many epochs or more is one its minutes end


@dataclass(frozen=True)
class Budget:
    """When a run stops (:func:`~.schedule.stop_reason`, which names why): its ``epochs`` are done,
    its wall-clock cap ``max_minutes`` (interrupted runs' time counted) is reached, or ``patience``
    epochs went by without a better validation score."""

    epochs: int
    max_minutes: float | None = None
    patience: float = math.inf
    # patience counts in the run's last fifth only (.schedule.early_stop); False: from the first epoch
    late_patience: bool = True
    # the cap stops a run before an epoch as long as the last would overrun it (.schedule.epoch_fits);
    # False: once the cap has passed
    whole_epochs: bool = True


@dataclass(frozen=True)
class Epoch:
    """What a stage's epoch gives the loop."""

    score: float  # the validation score the best weights are kept by (lower is better)
    log: dict = field(default_factory=dict)  # the epoch's line in log.jsonl, after its number
    postfix: dict = field(default_factory=dict)  # the progress bar's numbers


class TrainingRun:
    """A run in progress, what the step and the callbacks see: the model, the loop's plain
    ``state`` (the checkpoint's: epochs done, best score and its epoch, stale epochs, time spent,
    and the stage's own entries), the best weights so far and the clock."""

    def __init__(self, model: torch.nn.Module, budget: Budget, state: dict):
        self.model, self.budget, self.state = model, budget, state
        self.best_weights = {k: v.clone() for k, v in model.state_dict().items()}
        self.started, self.spent = time.perf_counter(), 0.0
        self.epoch_s: float | None = None  # the last epoch's duration

    def resumed(self) -> None:
        """Start the clock where the resumed state left it: the cap counts earlier runs' time too."""
        self.started, self.spent = time.perf_counter(), self.state["elapsed_s"]

    @property
    def elapsed_s(self) -> float:
        return self.spent + time.perf_counter() - self.started

    def progress(self, epoch: float) -> float:
        """How far the run is at ``epoch`` (fractional within one), 0 to 1
        (:func:`~.schedule.run_progress`)."""
        return run_progress(epoch, self.budget.epochs, self.elapsed_s, max_minutes=self.budget.max_minutes)

    def stop_reason(self) -> str | None:
        """Why the run stops before its next epoch, or None where it goes on."""
        budget = self.budget
        deadline = None if budget.max_minutes is None else self.started + 60 * budget.max_minutes - self.spent
        return stop_reason(
            self.state,
            budget,
            deadline=deadline,
            epoch_s=self.epoch_s if budget.whole_epochs else None,
            # at the run's end, early_stop counts the patience whatever the progress
            progress=self.progress(self.state["epoch"]) if budget.late_patience else 1.0,
        )

    def keep_if_best(self, score: float) -> None:
        """After an epoch scored ``score``: on a new best, record it and copy the model's weights;
        else count a stale epoch."""
        if score < self.state["best"]:
            self.state.update(best=score, best_epoch=self.state["epoch"], stale=0)
            self.best_weights = {k: v.detach().clone() for k, v in self.model.state_dict().items()}
        else:
            self.state["stale"] += 1


class EpochStep(ABC):
    """A stage's epoch: what :func:`fit` runs once an epoch."""

    def start(self, run: TrainingRun) -> None:
        """Called once, after resuming and before the first epoch (``run.state["epoch"]`` is the
        epoch the run resumes at): where a stage seeds what depends on it."""

    @abstractmethod
    def run_epoch(self, run: TrainingRun) -> Epoch:
        """Train epoch ``run.state["epoch"]`` (counted from 0), then validate it."""


class Callback:
    """Hears the loop; every hook does nothing unless overridden."""

    def on_fit_start(self, run: TrainingRun) -> None:
        """Before the first epoch (a checkpoint resumes here)."""

    def on_resumed(self, run: TrainingRun) -> None:
        """After every callback's :meth:`on_fit_start`: ``run.state`` is where the run goes on from."""

    def on_epoch_end(self, run: TrainingRun, epoch: Epoch) -> None:
        """After an epoch, counted in ``run.state`` and its best weights kept."""

    def on_fit_end(self, run: TrainingRun) -> None:
        """After the last epoch, before the best weights are put back."""


class ProgressBar(Callback):
    """A tqdm bar of the run's epochs (``desc``; none unless ``shown``) with the epoch's numbers and,
    where ``best`` is a format, the best score so far. A run of :data:`ENDLESS_EPOCHS` that its
    minutes end (hrr-make trains for minutes) counts its minutes instead."""

    def __init__(self, desc: str, shown: bool, best: str | None = None):
        self.desc, self.shown, self.best = desc, shown, best

    def on_fit_start(self, run: TrainingRun) -> None:
        budget = run.budget
        self.by_time = budget.max_minutes is not None and budget.epochs >= ENDLESS_EPOCHS
        self.bar = tqdm(
            total=budget.max_minutes if self.by_time else budget.epochs,
            initial=run.state["elapsed_s"] / 60 if self.by_time else run.state["epoch"],
            desc=self.desc,
            unit="min" if self.by_time else "epoch",
            disable=not self.shown,
            bar_format="{l_bar}{bar}| {n:.1f}/{total:.1f} min [{elapsed}{postfix}]" if self.by_time else None,
        )

    def on_epoch_end(self, run: TrainingRun, epoch: Epoch) -> None:
        best = {"best": self.best.format(run.state["best"])} if self.best else {}
        self.bar.set_postfix(
            **epoch.postfix, **best, **({"epoch": run.state["epoch"]} if self.by_time else {})
        )
        if self.by_time:
            self.bar.update(min(run.elapsed_s / 60, self.bar.total) - self.bar.n)
        else:
            self.bar.update(1)

    def on_fit_end(self, run: TrainingRun) -> None:
        self.bar.close()


# the loop's own entries of the state, after "epoch" and the stage's (the order of report.json's "training")
_LOOP_STATE = {"best": math.inf, "best_epoch": 0, "stale": 0, "elapsed_s": 0.0}


def fit(
    model: torch.nn.Module,
    step: EpochStep,
    budget: Budget,
    *,
    callbacks: Sequence[Callback] = (),
    state: dict | None = None,
) -> dict:
    """Train ``model`` by ``step``'s epochs until ``budget`` stops it (see the module docstring);
    the best validation epoch's weights are left in it, in eval mode. ``state``: the stage's own
    entries of the loop's state (checkpointed with it), with their values at the start. Returns the
    state at the end, with ``stopped``, why the run stopped (:mod:`.schedule`)."""
    run = TrainingRun(model, budget, {"epoch": 0, **(state or {}), **_LOOP_STATE})
    for callback in callbacks:
        callback.on_fit_start(run)
    for callback in callbacks:
        callback.on_resumed(run)
    run.resumed()
    step.start(run)
    while (stopped := run.stop_reason()) is None:
        epoch_started = time.perf_counter()
        epoch = step.run_epoch(run)
        run.state["epoch"] += 1
        run.state["elapsed_s"] = run.elapsed_s
        run.keep_if_best(epoch.score)
        for callback in callbacks:
            callback.on_epoch_end(run, epoch)
        run.epoch_s = time.perf_counter() - epoch_started
    for callback in callbacks:
        callback.on_fit_end(run)
    run.state["stopped"] = stopped
    model.load_state_dict(run.best_weights)
    model.eval()
    return run.state
