"""hrr-make's one progress display: a line as each stage starts (its place in the run, the time spent
so far, what the plan expects is left), the plan's table before the long work, the stages' own
progress bars between, and at the end each stage's time beside its estimate."""

from __future__ import annotations

import sys
import time
from contextlib import contextmanager
from dataclasses import dataclass

from ..pipeline.make_record import MakeRecord
from ..pipeline.train_settings import TrainCallback

STAGES = ("body", "motions", "probe", "simulate", "train", "onnx", "clips", "report")
LABELS = {
    "body": "the character's body and animations",
    "motions": "the motion library's features",
    "probe": "the simulator's compile and rate",
    "simulate": "simulating the chosen clips",
    "train": "training (autoencoder, code space, calibration)",
    "onnx": "the ONNX graph for this body",
    "clips": "the character's clips, GLB and preview",
    "report": "the report: held-out clips against their truth ensembles",
}


def clock(seconds: float) -> str:
    """``1:02:03`` or ``12:03``."""
    seconds = int(round(seconds))
    hours, rest = divmod(seconds, 3600)
    return f"{hours}:{rest // 60:02d}:{rest % 60:02d}" if hours else f"{rest // 60}:{rest % 60:02d}"


@dataclass
class StageTimer:
    """A stage's clock: its seconds so far, or in all once it ended."""

    started: float
    ended: float | None = None

    @property
    def seconds(self) -> float:
        return (self.ended or time.perf_counter()) - self.started


class _MakeTrainCallback(TrainCallback):
    """Training's messages as hrr-train prints them, read as a budget: hrr-make trains for minutes,
    so a cap ending a stage is the plan (not said), and an error above the preset's target is what
    the full recipe reaches, not these settings (said as a note)."""

    def on_message(self, text: str) -> None:
        print(text)

    def on_warning(self, text: str) -> None:
        if "cap stopped training" in text:
            return
        full = "these settings reach on an idle machine"
        if full in text:
            print(f"note: {text.replace(full, 'the full recipe reaches')} (a larger --budget comes nearer)")
        else:
            print(f"warning: {text}", file=sys.stderr)


class MakeProgress:
    """The display (``shown``: print it) over ``record``'s stages."""

    def __init__(self, record: MakeRecord, shown: bool = True):
        self.record, self.shown = record, shown
        self.started = time.perf_counter()
        # earlier runs' time on finished stages counts, so a resumed run's clock is the whole run's
        self.before = sum(s.get("seconds", 0.0) for s in record.stages.values())

    def elapsed(self) -> float:
        return self.before + time.perf_counter() - self.started

    def left(self, stage: str) -> float | None:
        """The plan's seconds for ``stage`` and every stage after it, or None before the plan."""
        estimates = dict(self.record.plan.get("estimates") or {})
        if not estimates:
            return None
        # training's minutes are decided again when the simulation ends (what the budget has left)
        estimates["train"] = self.record.plan.get("training", {}).get(
            "estimate_s", estimates.get("train", 0.0)
        )
        return sum(estimates.get(s, 0.0) for s in STAGES[STAGES.index(stage) :])

    @contextmanager
    def stage(self, name: str, quiet: bool = False):
        """Time a stage, announcing it (unless ``quiet``: a stage redone silently, cheap)."""
        if self.shown and not quiet:
            left = self.left(name)
            rest = f" · about {clock(left)} left" if left is not None else ""
            print(
                f"hrr-make [{STAGES.index(name) + 1}/{len(STAGES)}] {LABELS[name]} · "
                f"{clock(self.elapsed())} elapsed{rest}",
                flush=True,
            )
        timer = StageTimer(time.perf_counter())
        yield timer
        timer.ended = time.perf_counter()

    def show_plan(self) -> None:
        plan = self.record.plan
        if not self.shown or "budget" not in plan:
            return
        budget, frames = plan["budget"], plan["frames"]
        print(
            f"plan for a budget of {clock(budget['budget_s'])}: simulate {sum(frames.values()):,} frames "
            f"(train {frames['train']:,}, validation {frames['val']:,}, test {frames['test']:,}; "
            f"the library has {plan['library_frames']:,}) at {budget['sim_frames_per_s']:.1f} frames/s "
            f"(the probe's {self.record.stages['probe']['simulator_frames_per_s']:.1f}, lead-ins "
            "included); train the autoencoder "
            f"{budget['autoencoder_minutes']:.1f} min and the code space "
            f"{budget['codespace_minutes']:.1f} min"
        )
        for stage in STAGES:
            done = self.record.stages.get(stage, {}).get("seconds")
            estimate = plan["estimates"].get(stage, 0.0)
            state = f"took {clock(done)}" if done is not None else f"about {clock(estimate)}"
            print(f"  {stage:9s} {state:>16s}  {LABELS[stage]}")
        print(f"  {'total':9s} {'about ' + clock(budget['total_s']):>16s}", flush=True)

    def train_callback(self) -> TrainCallback:
        return _MakeTrainCallback()

    def finished(self) -> None:
        if not self.shown:
            return
        print(f"hrr-make: done in {clock(self.elapsed())}; each stage against the plan:")
        for stage in STAGES:
            entry = self.record.stages.get(stage, {})
            if "seconds" in entry:
                estimate = entry.get("estimate_s")
                ratio = f" ({entry['seconds'] / estimate:.2f} x its estimate)" if estimate else ""
                print(f"  {stage:9s} {clock(entry['seconds']):>9s}{ratio}")
