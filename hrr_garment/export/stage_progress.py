"""A progress display for work done in a few long stages that report nothing themselves (an ONNX
export: torch's trace of the step for minutes, then the optimiser, then the files): a tqdm bar of
the stages, named as each starts, whose clock keeps running while a stage works (the bar redrawn
once a second from a small thread), so that a user sees which stage runs and for how long.

    with stage_progress(("tracing the step", "optimising", "writing"), desc="ONNX export") as stage:
        stage("tracing the step")
        ...
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager

from tqdm.auto import tqdm

REDRAW_S = 1.0  # how often the clock on the bar moves while a stage works


@contextmanager
def stage_progress(
    stages: Sequence[str], *, desc: str, enabled: bool = True
) -> Iterator[Callable[[str], None]]:
    """A bar over ``stages``; the callable it yields starts the stage it names (one of ``stages``, in
    their order), the one before it counted done. Leaving the block counts the last stage done
    where no error left it. Disabled: nothing shown, no thread started."""
    bar = tqdm(
        total=len(stages),
        desc=desc,
        unit="stage",
        disable=not enabled,
        bar_format="{desc}: {n_fmt}/{total_fmt} stages [{elapsed}]{postfix}",
    )
    started: list[str] = []

    def start(name: str) -> None:
        if name not in stages:
            raise ValueError(f"{desc}: no stage {name!r} (its stages: {', '.join(stages)})")
        if started:
            bar.update(1)
        started.append(name)
        bar.set_postfix_str(name)

    done = threading.Event()
    ticker = None
    if enabled:

        def redraw() -> None:
            while not done.wait(REDRAW_S):
                bar.refresh()

        ticker = threading.Thread(target=redraw, name="stage-progress", daemon=True)
        ticker.start()
    try:
        yield start
        if started:
            bar.update(1)
            bar.set_postfix_str("done")
    finally:
        done.set()
        if ticker is not None:
            ticker.join()
        bar.close()
