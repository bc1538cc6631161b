"""The epoch loop (hrr_garment.train.loop): a budget of endless epochs is ended by its minutes and its
progress bar counts minutes; a budget of epochs ends at its epochs and counts them; the best epoch's
weights are the model's at the end; a run stopped at any point of an epoch's end goes on with one log
line per epoch."""

import json
import time

import pytest
import torch

from hrr_garment.train import checkpoint
from hrr_garment.train.checkpoint import Checkpoint, EpochLog
from hrr_garment.train.loop import ENDLESS_EPOCHS, Budget, Epoch, EpochStep, ProgressBar, fit


class _Steps(EpochStep):
    """An epoch of ``seconds`` whose score is best at epoch ``best`` (the weights record the epoch)."""

    def __init__(self, seconds: float, best: int):
        self.seconds, self.best = seconds, best

    def run_epoch(self, run):
        time.sleep(self.seconds)
        epoch = run.state["epoch"]
        with torch.no_grad():
            run.model.weight.fill_(epoch)
        return Epoch(score=abs(epoch - self.best))


def test_endless_epochs_end_at_their_minutes_and_count_minutes():
    model = torch.nn.Linear(1, 1)
    bar = ProgressBar("test", shown=True)  # a bar not shown counts nothing
    state = fit(model, _Steps(0.05, best=2), Budget(ENDLESS_EPOCHS, max_minutes=0.01), callbacks=[bar])
    assert state["stopped"] != "epochs" and 3 <= state["epoch"] < 20  # about 0.6 s of 0.05 s epochs
    assert bar.by_time and bar.bar.unit == "min" and bar.bar.total == 0.01
    assert 0 < bar.bar.n <= 0.01
    assert float(model.weight.detach()) == 2.0  # the best epoch's weights


def test_a_budget_of_epochs_counts_epochs():
    model = torch.nn.Linear(1, 1)
    bar = ProgressBar("test", shown=True)  # a bar not shown counts nothing
    state = fit(model, _Steps(0.0, best=1), Budget(4), callbacks=[bar])
    assert state["epoch"] == 4 and state["stopped"] == "epochs"
    assert not bar.by_time and bar.bar.n == 4
    assert float(model.weight.detach()) == 1.0


@pytest.mark.parametrize("stop", ["after the checkpoint", "between the log line and the checkpoint"])
def test_a_stopped_run_goes_on_with_one_log_line_per_epoch(tmp_path, monkeypatch, stop):
    """Ctrl-C at epoch 2's end, after its checkpoint or between its log line and its checkpoint: the
    run again trains the epochs the checkpoint lacks and logs each epoch once."""
    log, saved = tmp_path / "log.jsonl", tmp_path / "checkpoint.pt"
    save = checkpoint.save_checkpoint

    def save_then_stop(path, key, state, *args, **kwargs):
        if stop == "after the checkpoint" or state["epoch"] < 2:
            save(path, key, state, *args, **kwargs)
        if state["epoch"] == 2:
            raise KeyboardInterrupt

    def run(budget):
        model = torch.nn.Linear(1, 1)
        callbacks = [EpochLog(log), Checkpoint(saved, "k"), ProgressBar("test", shown=False)]
        return fit(model, _Steps(0.0, best=3), budget, callbacks=callbacks)

    with monkeypatch.context() as patch, pytest.raises(KeyboardInterrupt):
        patch.setattr(checkpoint, "save_checkpoint", save_then_stop)
        run(Budget(4))
    assert [json.loads(line)["epoch"] for line in log.read_text().splitlines()] == [1, 2]
    state = run(Budget(4))
    assert state["epoch"] == 4
    assert [json.loads(line)["epoch"] for line in log.read_text().splitlines()] == [1, 2, 3, 4]
