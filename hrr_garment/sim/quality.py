"""Quality statistics of garment sequences: penetration, edge strain, hem swing.

Used to reject exploded simulations, in the dataset summary, and by the evaluation metrics.
All functions take world-space vertices (T, V, 3) and work frame by frame to bound memory.
"""

from __future__ import annotations

import numpy as np

from ..body.capsules import DEFAULT_BODY, BodyModel, frames_signed_distance
from ..body.self_contact import self_intersecting_frames
from ..motion.frame import to_body_frame
from ..motion.motion import Motion
from .mesh_queries import mesh_signed_distances

PENETRATION_DEPTH_M = (
    0.005  # how far inside the body a vertex counts as penetrating (reports, evaluation, training)
)


def edge_strain(vertices: np.ndarray, rest: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """(T, E) edge length divided by rest length."""
    rest_len = np.linalg.norm(rest[edges[:, 0]] - rest[edges[:, 1]], axis=-1)
    cur = np.linalg.norm(vertices[:, edges[:, 0]] - vertices[:, edges[:, 1]], axis=-1)
    return cur / np.maximum(rest_len, 1e-12)


def body_signed_distance(vertices: np.ndarray, motion: Motion, body: BodyModel = DEFAULT_BODY) -> np.ndarray:
    """(T, V) signed distance of each vertex to the posed capsule body (negative inside)."""
    a, b = body.pose_motion(motion)
    chunk = 64  # frames at a time: the normals, which are not kept, stay small
    return (
        np.concatenate(
            [
                frames_signed_distance(
                    vertices[t : t + chunk], a[t : t + chunk], b[t : t + chunk], radii=body.radii
                )[0]
                for t in range(0, len(vertices), chunk)
            ]
        )
        if len(vertices)
        else np.zeros((0, vertices.shape[1]))
    )


def penetration_fraction(signed_distance: np.ndarray, depth: float = PENETRATION_DEPTH_M) -> np.ndarray:
    """(T,) fraction of vertices more than ``depth`` inside the body."""
    return (signed_distance < -depth).mean(axis=1)


def hem_swing(vertices: np.ndarray, motion: Motion, hem: np.ndarray) -> float:
    """Mean over hem vertices of the standard deviation (metres) of their position in the
    ground-level body frame (:func:`~hrr_garment.motion.frame.to_body_frame`).

    Zero for a garment rigidly skinned to the pelvis; a skirt that swings scores centimetres.
    """
    local = to_body_frame(vertices[:, hem], motion, ground=True)
    return float(np.sqrt(local.var(axis=0).sum(-1)).mean())


def sequence_stats(
    vertices: np.ndarray,
    rest: np.ndarray,
    edges: np.ndarray,
    motion: Motion,
    hem: np.ndarray | None = None,
    body: BodyModel = DEFAULT_BODY,
    visible=None,
) -> dict[str, float]:
    """Summary numbers for one sequence (see docs/dataset.md). ``visible``: the mesh a viewer sees of
    the body (a :class:`~hrr_garment.body.skinned_body.SkinnedBody`; None: the capsules are what is
    drawn, the mannequin), which the cloth inside is counted against, by winding number."""
    strain = edge_strain(vertices, rest, edges)
    sd = body_signed_distance(vertices, motion, body)
    pen = penetration_fraction(sd)
    if visible is None:
        seen = sd
    else:
        posed = visible.pose(motion.global_rotations, motion.joint_positions)
        seen = mesh_signed_distances(vertices, posed, visible.faces)
    inside = penetration_fraction(seen, depth=0.0)
    flagged = self_intersecting_frames(motion, body)  # limbs through the body: the capture's flaw
    stats = {
        "frames": int(len(vertices)),
        "finite": bool(np.isfinite(vertices).all()),
        "strain_p99": float(np.percentile(strain, 99)),
        "strain_max": float(strain.max()),
        "penetration_mean": float(pen.mean()),
        "penetration_max": float(pen.max()),
        "deepest_mm": float(max(0.0, -sd.min()) * 1000.0),
        # inside the body the viewer sees at all (the capsules' figures above count 5 mm in)
        "inside_visible_mean": float(inside.mean()),
        "inside_visible_max": float(inside.max()),
        "self_intersection_frames": int(flagged.sum()),
        "penetration_max_clean": float(pen[~flagged].max()) if (~flagged).any() else 0.0,
    }
    if hem is not None and len(hem):
        stats["hem_swing_m"] = hem_swing(vertices, motion, hem)
    return stats
