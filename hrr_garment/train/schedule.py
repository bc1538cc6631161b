"""When and how fast a training run goes: the device, the run's progress (by epochs or by the
wall-clock cap), whether another epoch fits the cap, early stopping, why a run stopped and the
cosine learning-rate schedule."""

from __future__ import annotations

import math
import time

import torch

from ..errors import InputError


def training_device(name: str) -> torch.device:
    """The torch device called ``name``, or a clear error when this machine has none such."""
    try:
        device = torch.device(name)
    except RuntimeError as exc:
        raise InputError("--device", f"{name!r} is not a torch device ({exc})") from None
    if device.type == "cuda" and not torch.cuda.is_available():
        raise InputError("--device", "CUDA was asked for, but this torch build or machine has no CUDA device")
    return device


def run_progress(epoch: float, epochs: int, elapsed_s: float, max_minutes: float | None) -> float:
    """How far the run is, 0 to 1: by epochs, or by the wall-clock budget when that ends first."""
    by_time = 0.0 if max_minutes is None else elapsed_s / (60.0 * max_minutes)
    return min(1.0, max(epoch / max(epochs, 1), by_time))


def epoch_fits(now: float, deadline: float | None, epoch_s: float | None) -> bool:
    """Whether another epoch, as long as the last one (``epoch_s``; None before the first), ends
    by ``deadline``. The budget is then a cap on training, not the last moment an epoch may
    start: on a slow hour of this 2-core machine a quick epoch takes 23 s, and starting one just
    before the deadline took the stage to 10.02 minutes with the encoding."""
    if deadline is None:
        return True
    return now + (epoch_s or 0.0) <= deadline


# why a run stopped (each stage's report.json, ``stopped``): its epochs were done, the validation error
# stopped improving, or the wall-clock cap (``max_minutes``) came first, which a busy or slow machine
# reaches sooner: the same command then gives a weaker model, and hrr-train says so
STOPPED_EPOCHS, STOPPED_EARLY, STOPPED_BY_CAP = "epochs", "early stop", "minutes cap"


def stop_reason(
    state: dict, config, *, deadline: float | None, epoch_s: float | None, progress: float
) -> str | None:
    """Why a run stops before its next epoch, or None where it goes on: its ``config.epochs`` are
    done, another epoch as long as the last would end past the cap's ``deadline``
    (:func:`epoch_fits`), or the validation error stopped improving (:func:`early_stop`, ``state``'s
    stale epochs against ``config.patience`` at the run's ``progress``)."""
    if state["epoch"] >= config.epochs:
        return STOPPED_EPOCHS
    if not epoch_fits(time.perf_counter(), deadline, epoch_s):
        return STOPPED_BY_CAP
    if early_stop(state["stale"], config.patience, progress):
        return STOPPED_EARLY
    return None


def cap_since_raised(stopped: str | None, cap_then: float | None, cap_now: float | None) -> bool:
    """Whether a finished run that its wall-clock cap (``cap_then`` minutes) cut short goes on under
    ``cap_now``: a re-run with a larger cap, or none, resumes its checkpoint and finishes the epochs
    it was asked for; one with the same cap keeps what it has."""
    return stopped == STOPPED_BY_CAP and (cap_now is None or (cap_then is not None and cap_now > cap_then))


def early_stop(stale_epochs: int, patience: int, progress: float) -> bool:
    """Stop after ``patience`` epochs without a better validation error, but only in the last fifth
    of the run, once the rate is below a tenth of its start. Before that the validation error can
    stall for dozens of epochs and then fall as the rate anneals: on the full dress (GPU) two runs
    stopped at epochs 53 and 58 with 4.8 and 4.7 mm, where the same settings run to the end of
    the schedule reached 4.0 mm."""
    return stale_epochs >= patience and progress >= 0.8


def set_learning_rate(optimizer: torch.optim.Optimizer, config, progress: float) -> float:
    """Cosine from ``learning_rate`` down to ``lr_final`` x it at the end of the run. Tied to the
    run's progress rather than to epochs, so a budgeted run (the quick preset) still ends with a
    small learning rate: with a per-epoch decay it stopped while the rate was high and the
    weights still noisy, and a long run froze long before its end. ``config``: a train config with
    ``learning_rate`` and ``lr_final``."""
    lo = config.learning_rate * config.lr_final
    lr = lo + 0.5 * (config.learning_rate - lo) * (
        1.0 + math.cos(math.pi * progress)
    )  # a float: the checkpoint holds it
    for group in optimizer.param_groups:
        group["lr"] = lr
    return lr
