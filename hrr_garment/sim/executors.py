"""Where the pending sequences of a build are simulated: a local process pool (or this process,
where one worker would do), or a Ray cluster.

Both run one sequence per worker (Warp's CPU kernels use one thread), or with ``batch`` N one
batch of up to N sequences of similar length per worker (:mod:`.batch`: one model on one device,
meant for a GPU), and end with the same part files; the builder then assembles the dataset from the
parts alone, so the dataset does not depend on which executor ran. Locally each worker writes its
own part; on Ray a task returns its part's content to the driver, which writes it, so a cluster
needs no shared filesystem (only the package, and the ``sim`` extra, installed on every node).
"""

from __future__ import annotations

import multiprocessing as mp
import os
import queue as queue_mod
from concurrent.futures import FIRST_COMPLETED, wait
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable

from tqdm.auto import tqdm

from ..body.mannequin import MANNEQUIN
from ..garment.dressing import DressedBody
from ..motion.motion import FPS, Motion
from ..workers import spawned_pool
from .config import SimSettings
from .lead_in import lead_in_frames
from .parts import PartResult, SequenceJob, simulate_sequence, simulate_sequences, write_part
from .plan import SequenceSpec

EXECUTORS = ("local", "ray")


def _frames_to_simulate(spec: SequenceSpec, config: SimSettings) -> int:
    lead = sum(lead_in_frames(config.settle_s, config.blend_s, FPS))
    return spec.frames + lead


@dataclass(frozen=True)
class Execution:
    """How the pending sequences of a build run: each one's part key, the parts folder, the worker
    processes (local) or CPUs of a local Ray instance (``jobs``), the progress bar, ``batch`` (up to
    this many sequences simulated together in one worker; 0 or 1: one at a time) and the Ray
    cluster to join (``address``)."""

    keys: dict[str, str]
    parts: Path
    jobs: int | None = None
    progress: bool = True
    batch: int = 0
    address: str | None = None


def batches(pending: list[SequenceSpec], config: SimSettings, size: int) -> list[list[SequenceSpec]]:
    """``pending`` in batches of up to ``size`` sequences of one cloth and similar length (longest
    first, so a batch's shorter instances idle little); ``size`` 0 or 1: one sequence each, in order."""
    if size <= 1:
        return [[s] for s in pending]
    by_cloth: dict = {}  # a batch is one model of one cloth
    for s in pending:
        by_cloth.setdefault(s.material, []).append(s)
    out = []
    for group in by_cloth.values():
        by_length = sorted(group, key=lambda s: -_frames_to_simulate(s, config))
        out += [by_length[k : k + size] for k in range(0, len(by_length), size)]
    return out


def _progress_bar(pending: list[SequenceSpec], config: SimSettings, progress: bool) -> tqdm:
    total = sum(_frames_to_simulate(s, config) for s in pending)
    return tqdm(total=total, unit="frame", desc="simulating", disable=not progress, smoothing=0.05)


def _finish(result: PartResult, rejects: dict[str, str], bar: tqdm) -> None:
    if result.failure is not None:
        rejects[result.name] = result.failure
        bar.write(f"rejected {result.name}: {result.failure}")


def _job(
    spec: SequenceSpec, bodies: dict[str, DressedBody], key: str, motion: Motion | None = None
) -> SequenceJob:
    """A sequence's job: the template on the mannequin, and its body where it names one (the
    motion loaded where the job runs when not given)."""
    body = bodies[spec.body_name] if spec.body_name else None
    return SequenceJob(spec, motion, garment=bodies[MANNEQUIN].garment, key=key, body=body)


def simulate_jobs(
    jobs: list[SequenceJob], config: dict, progress: Callable[[int], None] | None = None
) -> list[PartResult]:
    """Simulate one worker's share: a single sequence as :func:`~.parts.simulate_sequence` does, or
    a batch of several together (:func:`~.parts.simulate_sequences`); motions not yet loaded are."""
    jobs = [job if job.motion is not None else replace(job, motion=job.spec.motion()) for job in jobs]
    if len(jobs) == 1:
        job = jobs[0]
        return [
            simulate_sequence(
                job.spec,
                job.motion,
                job.garment,
                config=config,
                key=job.key,
                progress=progress,
                body=job.body,
            )
        ]
    return simulate_sequences(jobs, config, progress=progress)


# --- local process pool ------------------------------------------------------------------------


_PROGRESS = None  # in a local worker: the queue its simulated frames are counted on


def _start_local_worker(progress_queue) -> None:
    global _PROGRESS
    _PROGRESS = progress_queue


def _local_worker(
    jobs: list[SequenceJob], config: dict, parts: str, report: Callable[[int], None] | None = None
) -> list[PartResult]:
    """Simulate ``jobs`` and write their parts; the results without their arrays. Frames are counted
    on ``report``, or in a pool's worker on its progress queue."""
    report = report if report is not None else (_PROGRESS.put if _PROGRESS is not None else None)
    results = simulate_jobs(jobs, config, progress=report)
    for result in results:
        write_part(result, Path(parts))
    return [
        PartResult(r.name, r.key, r.frames, failure=r.failure) for r in results
    ]  # the arrays stay in the parts


def run_local(
    pending: list[SequenceSpec], bodies: dict[str, DressedBody], config: SimSettings, execution: Execution
) -> dict[str, str]:
    """Simulate ``pending`` in ``execution.jobs`` spawned processes, one sequence or batch
    (``execution.batch``) per task, or in this process where one worker would do; returns the
    rejected sequences' reasons. ``bodies``: the mannequin
    (:data:`~hrr_garment.body.mannequin.MANNEQUIN`, with the template) and every body a sequence
    names (:mod:`.body_plan`), each with the garment on it."""
    bar = _progress_bar(pending, config, execution.progress)
    rejects: dict[str, str] = {}
    if (execution.jobs or 1) == 1:
        # one worker would simulate the same sequences one after another, after starting Python and
        # loading the simulator again (about 7 s of a 25 s build of the tiny preset)
        return _run_here(pending, bodies, config, execution, bar, rejects)
    # handed to each worker as it starts: no manager process to outlive a kill
    progress_queue = mp.get_context("spawn").Queue()
    # Ctrl-C, SIGTERM, a crash: the other workers stopped now; a re-run resumes from the parts
    with spawned_pool(execution.jobs, _start_local_worker, progress_queue) as pool:
        remaining = {
            pool.submit(
                _local_worker,
                [_job(s, bodies, execution.keys[s.name]) for s in group],
                config.to_dict(),
                str(execution.parts),
            )
            for group in batches(pending, config, execution.batch)
        }
        while remaining:
            finished, remaining = wait(remaining, timeout=0.5, return_when=FIRST_COMPLETED)
            _drain(progress_queue, bar)
            for fut in finished:
                for result in fut.result():  # a worker crash propagates: the finished parts are kept
                    _finish(result, rejects, bar)
        _drain(progress_queue, bar)
    bar.close()
    return rejects


def _run_here(
    pending: list[SequenceSpec],
    bodies: dict[str, DressedBody],
    config: SimSettings,
    execution: Execution,
    bar: tqdm,
    rejects: dict[str, str],
) -> dict[str, str]:
    """:func:`run_local`'s one worker in this process: each part written as it finishes (a Ctrl-C
    or a kill keeps the finished ones, as a worker's do)."""
    settings = config.to_dict()
    for group in batches(pending, config, execution.batch):
        jobs = [_job(s, bodies, execution.keys[s.name]) for s in group]
        for result in _local_worker(jobs, settings, str(execution.parts), bar.update):
            _finish(result, rejects, bar)
    bar.close()
    return rejects


def _drain(progress_queue, bar) -> None:
    try:
        while True:
            bar.update(progress_queue.get_nowait())
    except queue_mod.Empty:
        pass


# --- Ray ---------------------------------------------------------------------------------------


def _import_ray():
    try:
        import ray
    except ImportError:
        raise ImportError("--executor ray needs Ray: pip install 'hrr_garment[cluster]'") from None
    return ray


def run_ray(
    pending: list[SequenceSpec], bodies: dict[str, DressedBody], config: SimSettings, execution: Execution
) -> dict[str, str]:
    """Simulate ``pending`` as Ray tasks, one sequence (or one batch, ``execution.batch``) each;
    parts are written here as tasks finish.

    ``execution.address`` joins a running cluster (``ray start --head`` prints it; "auto" finds a
    local one); without it a Ray instance with ``execution.jobs`` CPUs (default: all) is started in
    this process and shut down afterwards. A task asks for one CPU, and one GPU where the cluster
    has GPUs and the simulator's device is not "cpu". Motions are loaded here and sent with the task.
    """
    ray = _import_ray()
    started = not ray.is_initialized()
    if started:
        if execution.address:
            ray.init(address=execution.address, log_to_driver=False)
        else:
            ray.init(num_cpus=execution.jobs or os.cpu_count(), include_dashboard=False, log_to_driver=False)
    try:
        gpus = 1 if config.device != "cpu" and ray.cluster_resources().get("GPU", 0) >= 1 else 0
        task = ray.remote(num_cpus=1, num_gpus=gpus, max_retries=1)(simulate_jobs)
        config_ref = ray.put(config.to_dict())
        bar = _progress_bar(pending, config, execution.progress)
        rejects: dict[str, str] = {}
        frames = {s.name: _frames_to_simulate(s, config) for s in pending}
        remaining = [
            task.remote([_job(s, bodies, execution.keys[s.name], s.motion()) for s in group], config_ref)
            for group in batches(pending, config, execution.batch)
        ]  # the mannequin's sequences name no body
        while remaining:
            done, remaining = ray.wait(remaining, num_returns=1)
            for result in ray.get(done[0]):
                write_part(result, execution.parts)
                bar.update(frames[result.name])
                _finish(result, rejects, bar)
        bar.close()
        return rejects
    finally:
        if started:
            ray.shutdown()
