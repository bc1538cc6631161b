"""Study: how much of a fabric's bending rigidity the simulator's VBD solver delivers at a given
number of iterations (docs/materials.md).

Two 5 cm triangles meet at a level hinge; one is held, the other's free corner sags under gravity.
Converged, the corner hangs where the hinge's moment B * theta meets gravity's, m g h cos(theta)
(m = density * area / 3; for these triangles the map's moment is exactly B * theta): a known
answer. Per rigidity and iteration count the tool prints the simulated sag, the answer, and the
rigidity the sag implies as a share of the one asked for (1: delivered; 0.01: the cloth bends as if
a hundred times softer).

    python tools/studies/bending_convergence.py --bend 3e-5 3e-4 1e-3 --iterations 3 10 100 1000
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np
from scipy.optimize import brentq

from hrr_garment.garment.fabrics import FABRICS
from hrr_garment.garment.mesh import GarmentMesh
from hrr_garment.motion.motion import Motion
from hrr_garment.motion.skeleton import REST_PELVIS_HEIGHT
from hrr_garment.sim.simulator import SimSettings, simulate_garment

SIDE, HEIGHT, GRAVITY = 0.05, 0.95, 9.81


def hinge() -> GarmentMesh:
    """The held triangle and the free one, level, in front of the (still) body."""
    corners = [
        (0.0, HEIGHT, 0.3),
        (SIDE, HEIGHT, 0.3),
        (SIDE / 2, HEIGHT, 0.3 - SIDE),
        (SIDE / 2, HEIGHT, 0.3 + SIDE),
    ]
    return GarmentMesh(
        "hinge",
        np.array(corners, np.float32),
        np.array([(0, 2, 1), (0, 1, 3)], np.int32),
        groups={"held": np.array([0, 1, 2])},
        attached_groups=("held",),
    )


def sag(bend: float, density: float, iterations: int, seconds: float) -> float:
    """The hinge's angle (radians) after ``seconds`` of a still body."""
    frames = int(seconds * 30)
    still = Motion(
        np.tile(np.eye(3, dtype=np.float32), (frames, 22, 1, 1)),
        np.tile([0.0, REST_PELVIS_HEIGHT, 0.0], (frames, 1)),
    )
    material = replace(FABRICS["default"], density=density, bend=bend)
    config = SimSettings(material=material, air_drag=1.2, iterations=iterations, retries=0)
    corner = simulate_garment(hinge(), still, config).vertices[-1, 3]
    return float(np.arctan2(HEIGHT - corner[1], corner[2] - 0.3))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--bend", type=float, nargs="+", default=[3e-5, 3e-4, 1e-3], help="rigidities, N m")
    p.add_argument("--density", type=float, default=0.15, help="kg/m^2")
    p.add_argument("--iterations", type=int, nargs="+", default=[3, 10, 100, 1000])
    p.add_argument("--seconds", type=float, default=1.0, help="of standing still (after the lead-in)")
    args = p.parse_args(argv)
    moment = args.density * (SIDE * SIDE / 2) / 3 * GRAVITY * SIDE  # m g h
    print("| bend N m | iterations | sag deg | converged deg | rigidity delivered | seconds |")
    print("|---|---|---|---|---|---|")
    for bend in args.bend:
        answer = brentq(lambda t: bend * t - moment * np.cos(t), 0.0, np.pi / 2)
        for iterations in args.iterations:
            t0 = time.perf_counter()
            theta = sag(bend, args.density, iterations, args.seconds)
            delivered = moment * np.cos(theta) / max(theta, 1e-9) / bend
            print(
                f"| {bend:.0e} | {iterations} | {np.degrees(theta):.1f} | {np.degrees(answer):.1f} | "
                f"{delivered:.3f} | {time.perf_counter() - t0:.0f} |",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
