"""The contact phase's step against the body the viewer sees, timed: a dress on an anny body (the
bodies extra), the simulator-free dataset's clips on it, a code-space model of the default size with
random weights (speed does not depend on them), ``teach_contact``'s steps (64 frames a step) against
the skin and against the body's capsules; then the skin distance of one step's batch alone, forward
and backward, with and without leaving out the points far from the skin, on all threads and one.
Prints; asserts nothing.

    python tools/bench_visible_contact.py                   # 4,156 vertices requested, 10 steps
    python tools/bench_visible_contact.py --steps 20 --threads 16
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import torch


def _timed(fn, repeats: int) -> tuple[float, float]:
    """Median seconds of ``fn()``: wall-clock and this process's CPU time (all its threads; on a
    machine shared with other work the CPU time is the steadier)."""
    wall, cpu = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return float(np.median(wall)), float(np.median(cpu))


def _setup(vertices: int, rng: np.random.Generator) -> dict:
    """The dataset on anny's average body, a default-size model and the phase's windows."""
    from hrr_garment.body.body_file import record_of
    from hrr_garment.body.capsules import DEFAULT_BODY
    from hrr_garment.body.parametric import BodyShape, parametric_body
    from hrr_garment.data.dataset import GarmentDataset
    from hrr_garment.data.synthetic import write_synthetic_dataset
    from hrr_garment.data.windows import build_windows
    from hrr_garment.garment.dressing import dress
    from hrr_garment.garment.templates import make_garment
    from hrr_garment.models.codespace import CodeSpace, CodeSpaceSettings
    from hrr_garment.models.fcmae import AutoencoderSettings, MeshAutoencoder
    from hrr_garment.models.hierarchy import build_hierarchy
    from hrr_garment.motion.features import FeatureStats
    from hrr_garment.train.codespace_losses import WindowTensors
    from hrr_garment.train.contact import FrameDecoder

    garment = make_garment("dress", vertices)
    t0 = time.perf_counter()
    dressed, _ = dress("anny", record_of(parametric_body(BodyShape())), garment, made_for=DEFAULT_BODY)
    print(
        f"dress of {garment.num_vertices} vertices on anny's average body: {time.perf_counter() - t0:.0f} s"
    )
    folder = Path(tempfile.mkdtemp())
    ds = GarmentDataset(write_synthetic_dataset(folder / "anny.h5", garment, seconds=4.0, bodies=[dressed]))
    ae = MeshAutoencoder(
        build_hierarchy(garment.faces, garment.num_vertices), AutoencoderSettings(), garment.vertices, 0.02
    ).eval()
    cfg = CodeSpaceSettings()
    frames = {n: ds.sequence(n).motion.num_frames for n in ds.names}
    windows = build_windows(
        {n: rng.normal(size=(t, cfg.features)).astype(np.float32) for n, t in frames.items()},
        {n: rng.normal(size=(t, *ae.latent_shape)).astype(np.float32) for n, t in frames.items()},
        ds.names,
        window=cfg.window,
    )
    unit = FeatureStats(np.zeros(cfg.features, np.float32), np.ones(cfg.features, np.float32))
    latent_unit = FeatureStats(*(np.full(int(np.prod(ae.latent_shape)), v, np.float32) for v in (0.0, 1.0)))
    return {
        "ds": ds,
        "folder": folder,
        "windows": windows,
        "model": CodeSpace(cfg, cfg.features, ae.latent_shape),
        "decoder": FrameDecoder(ae, latent_unit),
        "tensors": WindowTensors.of(windows, unit, latent_unit),
    }


def _steps(setup: dict, contacts: dict, steps: int) -> None:
    """Whole steps of the phase, as training runs them."""
    from hrr_garment.train.codespace_losses import mean_square
    from hrr_garment.train.codespace_settings import CodeSpaceTrainSettings
    from hrr_garment.train.contact import ContactWindows, teach_contact

    for against, body in contacts.items():

        def run(against=against, body=body) -> None:
            (setup["folder"] / f"contact-{against}.pt").unlink(missing_ok=True)
            teach_contact(
                setup["model"],
                setup["decoder"],
                ContactWindows(setup["tensors"], body),
                val=None,
                config=CodeSpaceTrainSettings(contact_steps=steps),
                latent_loss=mean_square,
                checkpoint=(setup["folder"] / f"contact-{against}.pt", "bench"),
                progress=False,
            )

        wall, cpu = _timed(run, 1)
        print(f"a step against {against}: {1e3 * wall / steps:.0f} ms ({1e3 * cpu / steps:.0f} ms of CPU)")


def _batch(setup: dict, visible, rng: np.random.Generator, repeats: int) -> None:
    """One step's batch (64 random stored frames of the garment, in the body frame): what the skin
    distance says of it beside the exact distance to the posed mesh, and its time."""
    from hrr_garment.body.mesh_distance import mesh_signed_distance
    from hrr_garment.motion.frame import to_body_frame

    ds, names = setup["ds"], setup["windows"].names
    frames = np.concatenate(
        [to_body_frame(ds.sequence(n).garment.astype(np.float64), ds.sequence(n).motion) for n in names]
    )
    rows = torch.from_numpy(rng.choice(len(frames), 64, replace=False))
    points = torch.from_numpy(frames[rows.numpy()].astype(np.float32))
    d = visible.distance(points, rows, 0.002).numpy()
    every = visible.distance(points, rows, np.inf).numpy()
    rot = visible.visible.rotations[rows.numpy()].astype(np.float64)
    pos = visible.visible.positions[rows.numpy()].astype(np.float64)
    envelope = visible.visible.envelopes[0]
    posed = envelope.pose(rot, pos)  # the skin in the body frame
    faces = ds.bodies["anny"].visible.faces
    exact = np.stack([mesh_signed_distance(points[t].numpy(), posed[t], faces) for t in range(8)])
    changed, near = d != every, every <= 0.002
    held = changed[:8] & near[:8]

    def pct(mask: np.ndarray) -> str:
        return f"{100 * float(mask.mean()):.1f} %"

    print(f"batch {tuple(points.shape)}, more than 5 mm inside the skin: {pct(d < -0.005)}")
    print(f"  on 8 frames, the exact distance {pct(exact < -0.005)}, the collider {pct(every[:8] < -0.005)}")
    print(f"  within the 2 mm margin {pct(near)}; left out or raised to the bound {pct(changed)}")
    print(
        f"  changed where the collider says within the margin: {int((changed & near).sum())} points "
        f"(8 frames: {int(held.sum())}, of which the exact distance puts "
        f"{int((held & (exact <= 0.002)).sum())} there)"
    )

    def step(reach: float) -> None:
        x = points.clone().requires_grad_(True)
        torch.relu(0.002 - visible.distance(x, rows, reach)).mean().backward()

    grown = _timed(lambda: envelope.grown(rot, pos), repeats)[1]
    for threads in sorted({torch.get_num_threads(), 1}, reverse=True):
        torch.set_num_threads(threads)
        culled, whole = _timed(lambda: step(0.002), repeats), _timed(lambda: step(np.inf), repeats)
        print(
            f"{threads} threads: skin distance forward+backward {1e3 * culled[0]:.0f} ms "
            f"({1e3 * culled[1]:.0f} ms of CPU, {1e3 * grown:.0f} of it growing the capsules) with the far "
            f"points left out, {1e3 * whole[0]:.0f} ms ({1e3 * whole[1]:.0f} ms of CPU) with every point "
            f"asked: {1e6 * whole[1] / points[..., 0].numel():.2f} us of CPU a point"
        )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--vertices", type=int, default=4156, help="the dress's vertices, as requested")
    p.add_argument("--steps", type=int, default=10)
    p.add_argument("--threads", type=int, default=None, help="torch's (and so the queries') threads")
    p.add_argument("--repeats", type=int, default=5)
    args = p.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    from hrr_garment.train.contact import BodyContacts

    torch.manual_seed(0)
    rng = np.random.default_rng(0)
    setup = _setup(args.vertices, rng)
    contacts = {}
    for against in ("visible", "capsules"):
        t0 = time.perf_counter()
        contacts[against] = BodyContacts.of(setup["ds"], setup["windows"], against)
        print(f"contacts against {against}: {time.perf_counter() - t0:.1f} s to build")
    print(f"threads: {torch.get_num_threads()}; {len(setup['windows'].motion.frames)} stored frames")
    _steps(setup, contacts, args.steps)
    _batch(setup, contacts["visible"], rng, args.repeats)


if __name__ == "__main__":
    main()
