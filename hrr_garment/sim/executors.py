"""Where the pending sequences of a build are simulated: a local process pool, or a Ray cluster.

Both run one sequence per worker (Warp's CPU kernels use one thread) and end with the same part
files; the builder then assembles the dataset from the parts alone, so the dataset does not depend
on which executor ran. Locally each worker writes its own part; on Ray a task returns its part's
content to the driver, which writes it, so a cluster needs no shared filesystem (only the package,
and the ``sim`` extra, installed on every node).
"""

from __future__ import annotations

import multiprocessing as mp
import os
import queue as queue_mod
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from pathlib import Path

from tqdm.auto import tqdm

from ..data.bodies import MANNEQUIN, DressedBody
from ..garment.mesh import GarmentMesh
from ..motion.motion import FPS
from .config import SimConfig
from .lead_in import lead_in_frames
from .parts import PartResult, simulate_sequence, write_part
from .plan import SequenceSpec

EXECUTORS = ("local", "ray")


def _frames_to_simulate(spec: SequenceSpec, config: SimConfig) -> int:
    lead = sum(lead_in_frames(config.settle_s, config.blend_s, FPS))
    return (int(round(spec.seconds * FPS)) if spec.kind != "file" else spec.stop - spec.start) + lead


def _progress_bar(pending: list[SequenceSpec], config: SimConfig, progress: bool) -> tqdm:
    total = sum(_frames_to_simulate(s, config) for s in pending)
    return tqdm(total=total, unit="frame", desc="simulating", disable=not progress, smoothing=0.05)


def _finish(result: PartResult, rejects: dict[str, str], bar: tqdm) -> None:
    if result.failure is not None:
        rejects[result.name] = result.failure
        bar.write(f"rejected {result.name}: {result.failure}")


# --- local process pool ------------------------------------------------------------------------


def _on_body(spec: SequenceSpec, bodies: dict[str, DressedBody]) -> tuple[GarmentMesh, DressedBody | None]:
    """The garment a sequence is simulated with, and its body where it names one."""
    if spec.body:
        return bodies[spec.body].garment, bodies[spec.body]
    return bodies[MANNEQUIN].garment, None


def _local_worker(spec: SequenceSpec, garment: GarmentMesh, config: dict, key: str, parts: str,
                  progress_queue=None, body: DressedBody | None = None) -> PartResult:
    report = progress_queue.put if progress_queue is not None else None
    result = simulate_sequence(spec, spec.motion(), garment, config=config, key=key, progress=report, body=body)
    write_part(result, Path(parts))
    return PartResult(result.name, key, result.frames, failure=result.failure)  # the arrays stay in the part


def run_local(pending: list[SequenceSpec], bodies: dict[str, DressedBody], config: SimConfig, *, keys: dict[str, str],
              parts: Path, jobs: int, progress: bool) -> dict[str, str]:
    """Simulate ``pending`` in ``jobs`` spawned processes; returns the rejected sequences' reasons.
    ``bodies``: the mannequin (:data:`~hrr_garment.data.bodies.MANNEQUIN`, with the template) and
    every body a sequence names (:mod:`.bodies`), each with the garment on it."""
    bar = _progress_bar(pending, config, progress)
    rejects: dict[str, str] = {}
    ctx = mp.get_context("spawn")  # Warp is not fork-safe
    with ctx.Manager() as manager, ProcessPoolExecutor(max_workers=jobs, mp_context=ctx) as pool:
        progress_queue = manager.Queue()
        futures = set()
        for s in pending:
            garment, body = _on_body(s, bodies)
            futures.add(pool.submit(_local_worker, s, garment, config.to_dict(), keys[s.name], str(parts), progress_queue, body))
        remaining = set(futures)
        while remaining:
            finished, remaining = wait(remaining, timeout=0.5, return_when=FIRST_COMPLETED)
            _drain(progress_queue, bar)
            for fut in finished:
                _finish(fut.result(), rejects, bar)  # a worker crash propagates: the finished parts are kept
        _drain(progress_queue, bar)
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


def run_ray(pending: list[SequenceSpec], bodies: dict[str, DressedBody], config: SimConfig, *, keys: dict[str, str],
            parts: Path, jobs: int | None, progress: bool, address: str | None = None) -> dict[str, str]:
    """Simulate ``pending`` as Ray tasks, one sequence each; parts are written here as tasks finish.

    ``address`` joins a running cluster (``ray start --head`` prints it; "auto" finds a local one);
    without it a Ray instance with ``jobs`` CPUs (default: all) is started in this process and shut
    down afterwards. A task asks for one CPU, and one GPU where the cluster has GPUs and the
    simulator's device is not "cpu". Motions are loaded here and sent with the task.
    """
    ray = _import_ray()
    started = not ray.is_initialized()
    if started:
        if address:
            ray.init(address=address, log_to_driver=False)
        else:
            ray.init(num_cpus=jobs or os.cpu_count(), include_dashboard=False, log_to_driver=False)
    try:
        gpus = 1 if config.device != "cpu" and ray.cluster_resources().get("GPU", 0) >= 1 else 0
        task = ray.remote(num_cpus=1, num_gpus=gpus, max_retries=1)(simulate_sequence)
        config_ref = ray.put(config.to_dict())
        body_refs = {name: ray.put(body) for name, body in bodies.items()}
        garment_refs = {name: ray.put(body.garment) for name, body in bodies.items()}
        bar = _progress_bar(pending, config, progress)
        rejects: dict[str, str] = {}
        frames = {s.name: _frames_to_simulate(s, config) for s in pending}
        remaining = [task.remote(s, s.motion(), garment_refs[s.body or MANNEQUIN], config_ref, keys[s.name], None,
                                 body_refs[s.body] if s.body else None)
                     for s in pending]  # the mannequin's sequences name no body: their parts stay as before
        while remaining:
            done, remaining = ray.wait(remaining, num_returns=1)
            result: PartResult = ray.get(done[0])
            write_part(result, parts)
            bar.update(frames[result.name])
            _finish(result, rejects, bar)
        bar.close()
        return rejects
    finally:
        if started:
            ray.shutdown()
