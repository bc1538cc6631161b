"""Resumable training checkpoints, one format for every training stage.

A checkpoint holds the settings key it was made under, the loop's plain ``state`` (epoch, best
score, elapsed time... as JSON), the best weights so far, torch's RNG state and the state dict of
every named stateful object (model, optimizer, scheduler...). It is written atomically after each
epoch (:class:`Checkpoint`, a callback of the training loop :mod:`.loop`); a checkpoint made under
other settings is ignored, so changed settings start afresh. Beside it a stage may keep one JSON
line per epoch (:class:`EpochLog`), cut back to the checkpoint's epoch on resuming.
"""

from __future__ import annotations

import json
from pathlib import Path

import torch

from ..io_utils import atomic_path, atomic_write_text, strict_json
from .loop import Callback, Epoch, TrainingRun


def save_checkpoint(path: Path, key: str, state: dict, best_weights: dict, **stateful) -> None:
    """Write the loop's state, best weights, RNG and the ``stateful`` objects atomically."""
    with atomic_path(path) as tmp:
        torch.save(
            {
                "key": key,
                "state": json.dumps(state),
                "best_weights": best_weights,
                "rng": torch.get_rng_state(),
                **{name: obj.state_dict() for name, obj in stateful.items()},
            },
            tmp,
        )


def load_checkpoint(path: Path, key: str, state: dict, best_weights: dict, **stateful) -> tuple[dict, dict]:
    """Restore ``stateful`` objects in place from ``path`` when it was saved under ``key``; returns
    (state, best_weights), the given ones when there is nothing to resume."""
    if not path.exists():
        return state, best_weights
    saved = torch.load(path, map_location="cpu", weights_only=True)
    if saved.get("key") != key or "state" not in saved:
        return state, best_weights
    for name, obj in stateful.items():
        obj.load_state_dict(saved[name])
    torch.set_rng_state(saved["rng"])
    return {**state, **json.loads(saved["state"])}, saved["best_weights"]


def resume_log(path: Path, epoch: int) -> None:
    """Make a JSON-lines epoch log agree with a checkpoint at ``epoch``: empty when starting afresh,
    else without the lines of epochs after it (a kill between the two writes)."""
    if epoch == 0:
        path.unlink(missing_ok=True)
    elif path.exists():
        lines = [line for line in path.read_text().splitlines() if json.loads(line)["epoch"] <= epoch]
        atomic_write_text(path, "".join(line + "\n" for line in lines))


class Checkpoint(Callback):
    """Resume from ``path`` when it was saved under ``key``, and save there after every epoch: the
    loop's state, the best weights, torch's RNG and the model's and the ``stateful`` objects'
    states (optimizer, scheduler... by name)."""

    def __init__(self, path: Path, key: str, **stateful):
        self.path, self.key, self.stateful = path, key, stateful

    def _objects(self, run: TrainingRun) -> dict:
        return {"model": run.model, **self.stateful}

    def on_fit_start(self, run: TrainingRun) -> None:
        run.state, run.best_weights = load_checkpoint(
            self.path, self.key, run.state, best_weights=run.best_weights, **self._objects(run)
        )

    def on_epoch_end(self, run: TrainingRun, epoch: Epoch) -> None:
        save_checkpoint(self.path, self.key, run.state, best_weights=run.best_weights, **self._objects(run))


class EpochLog(Callback):
    """One JSON line per epoch in ``path``: its number and the step's ``Epoch.log``; on resuming,
    the lines after the checkpoint's epoch are dropped (:func:`resume_log`). Give it before the
    :class:`Checkpoint`: an epoch's line is written before its checkpoint, so none is lost."""

    def __init__(self, path: Path):
        self.path = path

    def on_resumed(self, run: TrainingRun) -> None:
        resume_log(self.path, run.state["epoch"])

    def on_epoch_end(self, run: TrainingRun, epoch: Epoch) -> None:
        with open(self.path, "a", encoding="utf-8") as fh:
            fh.write(strict_json({"epoch": run.state["epoch"], **epoch.log}) + "\n")
