"""BVH writing: a skeleton and its motion as a BVH file (any Euler order per joint, 3 or 6 channels,
any unit), the layouts real exporters produce, so the reader (:mod:`.bvh`) is tested against them."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..io_utils import atomic_write_text
from .rotations import matrix_to_euler


@dataclass(frozen=True)
class BvhStyle:
    """How :func:`write_bvh` lays a motion out: one Euler order for all joints or one per joint;
    with ``positions_on_all_joints`` every joint gets six channels (its offset keyed every frame);
    ``unit_scale`` converts metres to file units (e.g. 100 for centimetres); ``end_sites``: the End
    Site offset of a leaf joint (metres; zero where not given)."""

    orders: list[str] | str = "ZYX"
    positions_on_all_joints: bool = False
    unit_scale: float = 1.0
    end_sites: dict[int, np.ndarray] | None = None


def write_bvh(
    path: str | Path,
    names: list[str],
    parents: list[int],
    offsets: np.ndarray,
    local_rotations: np.ndarray,
    root_translation: np.ndarray,
    frame_time: float,
    style: BvhStyle = BvhStyle(),
) -> None:
    """Write a BVH of a skeleton (``names``, ``parents``, ``offsets`` in metres) and its motion,
    laid out as ``style`` says (:class:`BvhStyle`: Euler orders, channels, units, End Sites)."""
    orders, positions_on_all_joints, unit_scale = (
        style.orders,
        style.positions_on_all_joints,
        style.unit_scale,
    )
    end_sites = style.end_sites
    n_joints = len(names)
    orders = [orders] * n_joints if isinstance(orders, str) else list(orders)
    end_sites = end_sites or {}
    children = {j: [c for c, p in enumerate(parents) if p == j] for j in range(n_joints)}
    out: list[str] = ["HIERARCHY"]

    def emit(j: int, depth: int) -> None:
        ind = "\t" * depth
        kind = "ROOT" if parents[j] < 0 else "JOINT"
        out.append(f"{ind}{kind} {names[j]}")
        out.append(f"{ind}{{")
        off = offsets[j] * unit_scale
        out.append(f"{ind}\tOFFSET {off[0]:.6f} {off[1]:.6f} {off[2]:.6f}")
        rot = " ".join(f"{a}rotation" for a in orders[j])
        if parents[j] < 0 or positions_on_all_joints:
            out.append(f"{ind}\tCHANNELS 6 Xposition Yposition Zposition {rot}")
        else:
            out.append(f"{ind}\tCHANNELS 3 {rot}")
        for c in children[j]:
            emit(c, depth + 1)
        if not children[j]:
            site = end_sites.get(j, np.zeros(3)) * unit_scale
            out.extend(
                [
                    f"{ind}\tEnd Site",
                    f"{ind}\t{{",
                    f"{ind}\t\tOFFSET {site[0]:.6f} {site[1]:.6f} {site[2]:.6f}",
                    f"{ind}\t}}",
                ]
            )
        out.append(f"{ind}}}")

    emit(parents.index(-1), 0)
    n_frames = local_rotations.shape[0]
    out += ["MOTION", f"Frames: {n_frames}", f"Frame Time: {frame_time:.8f}"]
    cols = []

    def visit(j: int) -> None:
        if parents[j] < 0:
            cols.append(root_translation * unit_scale)
        elif positions_on_all_joints:
            cols.append(np.broadcast_to(offsets[j] * unit_scale, (n_frames, 3)))
        cols.append(matrix_to_euler(local_rotations[:, j], orders[j]))
        for c in children[j]:
            visit(c)

    visit(parents.index(-1))
    data = np.concatenate(cols, axis=1)
    out += [" ".join(f"{v:.6f}" for v in row) for row in data]
    atomic_write_text(path, "\n".join(out) + "\n")
