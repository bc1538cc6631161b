"""The inverse-skinning collider's query rate on one core: points per second of the numpy reference
(hrr_garment.body.skin_collider) and of the C kernel (hrr_garment.native.skin), on an anny body
(the bodies extra) posed by frames of a procedural dance, the points spread over the posed mesh
and up to 2 cm off it both ways (where a push-out asks). With ``--torch``, also its torch graph
(hrr_garment.models.skin_collider_graph, float32, one thread and two) and that graph exported to
ONNX and run by onnxruntime (one thread and two; the ``onnx`` extra), each timed right after the C
kernel on the same frame and given as a fraction of its rate (the median over frames, so that a
loaded machine's drift cancels), with its largest departure from the reference's distance.
Prints; asserts nothing.

    python tools/bench_skin_sdf.py --points 4156 --repeats 20
    python tools/bench_skin_sdf.py --torch --frames 4 --repeats 10
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--points", type=int, default=4156, help="points a query (one dress: 4,156)")
    p.add_argument("--repeats", type=int, default=20, help="C queries timed a frame")
    p.add_argument("--frames", type=int, default=4)
    p.add_argument("--torch", action="store_true", help="the torch graph and its ONNX export too")
    args = p.parse_args()
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    from hrr_garment.body.body_file import record_of
    from hrr_garment.body.parametric import BodyShape, parametric_body
    from hrr_garment.body.retarget import motion_on_body
    from hrr_garment.body.skin_collider import skin_collider
    from hrr_garment.body.skinned_body import visible_body
    from hrr_garment.motion.synth import synthesize
    from hrr_garment.native import load_kernel
    from hrr_garment.native.skin import SkinKernel

    record = record_of(parametric_body(BodyShape()))
    visible = visible_body(record)
    t0 = time.perf_counter()
    collider = skin_collider(visible)
    print(
        f"built in {time.perf_counter() - t0:.1f} s: "
        f"{len(collider.distance):,} nodes, {collider.nbytes / 1e6:.1f} MB"
    )
    lib = load_kernel()
    kernel = SkinKernel(collider, lib) if lib is not None else None
    motion = motion_on_body(synthesize("dance", 4.0), record)
    rng = np.random.default_rng(0)
    rates: dict[str, list[float]] = {"numpy": [], "C": []}
    others = _graphs(collider) if args.torch else {}
    worst, ratios = dict.fromkeys(others, 0.0), {name: [] for name in others}
    for t in np.linspace(0, motion.num_frames - 1, args.frames).astype(int):
        rot, pos = motion.global_rotations[t], motion.joint_positions[t]
        points = _points(visible, visible.pose(rot[None], pos[None])[0], args.points, rng)
        t0 = time.perf_counter()
        reference = collider.query(points, rot, pos)[0]
        rates["numpy"].append(args.points / (time.perf_counter() - t0))
        if kernel is None:
            continue
        rates["C"].append(_rate(kernel.query, (points, rot, pos), args.repeats))
        for name, query in others.items():  # each right after the C kernel's own, on the same frame
            worst[name] = max(worst[name], float(np.abs(query(points, rot, pos) - reference).max()))
            c_rate = _rate(kernel.query, (points, rot, pos), args.repeats)
            rates.setdefault(name, []).append(_rate(query, (points, rot, pos), args.repeats))
            ratios[name].append(rates[name][-1] / c_rate)
    for name, values in rates.items():
        if values:
            rate = float(np.median(values))
            relative = f", {np.median(ratios[name]):.3f} x the C kernel's rate" if ratios.get(name) else ""
            departs = f", distance within {worst[name]:.1e} m of the reference" if name in worst else ""
            print(
                f"{name}: {rate:,.0f} points/s, {1e3 * args.points / rate:.2f} ms a query of "
                f"{args.points}{relative}{departs}"
            )


def _points(visible, posed: np.ndarray, count: int, rng: np.random.Generator) -> np.ndarray:
    """``count`` points spread over the ``posed`` mesh, each up to 2 cm off it along its normal."""
    from hrr_garment.body.mesh_distance import surface_samples, vertex_normals

    face, bary = surface_samples(posed, visible.faces, count, rng=rng)
    corners = visible.faces[face]
    normal = np.einsum("nk,nkc->nc", bary, vertex_normals(posed, visible.faces)[corners])
    return np.einsum("nk,nkc->nc", bary, posed[corners]) + rng.uniform(-0.02, 0.02, (count, 1)) * normal


def _rate(query, args: tuple, repeats: int) -> float:
    """Points a second of ``query(*args)``, warmed by one call, over ``repeats`` calls."""
    query(*args)
    t0 = time.perf_counter()
    for _ in range(repeats):
        query(*args)
    return len(args[0]) * repeats / (time.perf_counter() - t0)


def _graphs(collider) -> dict:
    """The torch graph (float32) at one thread and two, and its ONNX export run by onnxruntime at one
    thread and two, each as ``query(points, rotations, positions) -> (N,) distance``."""
    import tempfile
    from pathlib import Path

    import torch

    from hrr_garment.models.skin_collider_graph import SkinColliderGraph

    graph = SkinColliderGraph(collider, torch.float32).eval()

    def torch_query(threads: int):
        def query(points, rot, pos):
            torch.set_num_threads(threads)
            with torch.no_grad():
                args = (torch.as_tensor(a, dtype=torch.float32) for a in (points, rot, pos))
                return graph(*args)[0].numpy()

        return query

    out = {"torch float32, 1 thread": torch_query(1), "torch float32, 2 threads": torch_query(2)}
    try:
        import onnxruntime

        from hrr_garment.export.skin_collider_onnx import export_skin_collider
    except ImportError:
        print("no onnxruntime or onnx: the ONNX graph is left out")
        return out
    t0 = time.perf_counter()
    path = export_skin_collider(collider, Path(tempfile.mkdtemp()) / "body.onnx")
    print(f"exported in {time.perf_counter() - t0:.1f} s: {path.stat().st_size / 1e6:.1f} MB")

    def onnx_query(threads: int):
        options = onnxruntime.SessionOptions()
        options.intra_op_num_threads, options.inter_op_num_threads = threads, 1
        session = onnxruntime.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])

        def query(points, rot, pos):
            feed = {"points": points[None], "rotations": rot[None], "positions": pos[None]}
            return session.run(["distance"], {k: v.astype(np.float32) for k, v in feed.items()})[0][0]

        return query

    return out | {
        "onnxruntime float32, 1 thread": onnx_query(1),
        "onnxruntime float32, 2 threads": onnx_query(2),
    }


if __name__ == "__main__":
    main()
