"""The inverse-skinning collider's query rate on one core: points per second of the numpy reference
(hrr_garment.body.skin_collider) and of the C kernel (hrr_garment.native.skin), on an anny body
(the bodies extra) posed by the most bent frames of a procedural clip, the points spread over the
posed mesh and up to 2 cm off it both ways (where a push-out asks). Prints; asserts nothing.

    python tools/bench_skin_sdf.py --points 4156 --repeats 20
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
    args = p.parse_args()
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    from hrr_garment.body.body_file import record_of
    from hrr_garment.body.mesh_distance import surface_samples, vertex_normals
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
    for t in np.linspace(0, motion.num_frames - 1, args.frames).astype(int):
        rot, pos = motion.global_rotations[t], motion.joint_positions[t]
        posed = visible.pose(rot[None], pos[None])[0]
        face, bary = surface_samples(posed, visible.faces, args.points, rng=rng)
        corners = visible.faces[face]
        normal = np.einsum("nk,nkc->nc", bary, vertex_normals(posed, visible.faces)[corners])
        points = (
            np.einsum("nk,nkc->nc", bary, posed[corners])
            + rng.uniform(-0.02, 0.02, (args.points, 1)) * normal
        )
        t0 = time.perf_counter()
        collider.query(points, rot, pos)
        rates["numpy"].append(args.points / (time.perf_counter() - t0))
        if kernel is not None:
            t0 = time.perf_counter()
            for _ in range(args.repeats):
                kernel.query(points, rot, pos)
            rates["C"].append(args.points * args.repeats / (time.perf_counter() - t0))
    for name, values in rates.items():
        if values:
            rate = float(np.median(values))
            print(
                f"{name}: {rate:,.0f} points/s on one core, "
                f"{1e3 * args.points / rate:.2f} ms a query of {args.points}"
            )


if __name__ == "__main__":
    main()
