"""Resumable training checkpoints, one format for every training stage.

A checkpoint holds the settings key it was made under, the loop's plain ``state`` (epoch, best
score, elapsed time... as JSON), the best weights so far, torch's RNG state and the state dict of
every named stateful object (model, optimizer, scheduler...). It is written atomically after each
epoch; a checkpoint made under other settings is ignored, so changed settings start afresh.
"""

from __future__ import annotations

import json
from pathlib import Path

import torch

from ..io_utils import atomic_path


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


def keep_if_best(state: dict, score: float, model: torch.nn.Module, best_weights: dict) -> dict:
    """Early-stopping bookkeeping after an epoch scored ``score`` (lower is better): on a new best,
    record it in ``state`` and return a copy of the model's weights; else count a stale epoch and
    return ``best_weights`` unchanged."""
    if score < state["best"]:
        state.update(best=score, best_epoch=state["epoch"], stale=0)
        return {k: v.detach().clone() for k, v in model.state_dict().items()}
    state["stale"] += 1
    return best_weights


def resume_log(path: Path, epoch: int) -> None:
    """Make a JSON-lines epoch log agree with a checkpoint at ``epoch``: empty when starting afresh,
    else without the lines of epochs after it (a kill between the two writes)."""
    if epoch == 0:
        path.unlink(missing_ok=True)
    elif path.exists():
        lines = [line for line in path.read_text().splitlines() if json.loads(line)["epoch"] <= epoch]
        path.write_text("".join(line + "\n" for line in lines))
