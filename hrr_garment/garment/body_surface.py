"""Where the capsule body's surface is in the canonical rest pose, as the templates are fitted to
it: the body's capsules at rest, the radius a ray from the body axis meets it at, points pushed out
of it, and the body's top surface under a shoulder strap."""

from __future__ import annotations

import numpy as np

from ..body.capsules import DEFAULT_BODY, BodyModel, capsule_signed_distance


def rest_body(body: BodyModel = DEFAULT_BODY) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Capsule ends a, b (C, 3) and radii (C,) of the body in the canonical rest pose."""
    a, b = body.rest_pose()
    return a, b, body.radii


def body_fit_radius(
    theta: np.ndarray,
    height: np.ndarray,
    gap: float,
    body: BodyModel = DEFAULT_BODY,
    max_radius: float = 0.6,
    step: float = 0.004,
) -> np.ndarray:
    """Distance from the vertical body axis, along angle ``theta`` at ``height``, to ``gap`` outside
    the body's outer surface (0 where the ray misses the body). Marches inwards, then bisects."""
    a, b, radii = rest_body(body)
    theta, height = np.broadcast_arrays(np.asarray(theta, float), np.asarray(height, float))
    shape = theta.shape
    theta, height = theta.ravel(), height.ravel()
    direction = np.stack([np.sin(theta), np.zeros_like(theta), np.cos(theta)], -1)
    origin = np.stack([np.zeros_like(height), height, np.zeros_like(height)], -1)
    ts = np.arange(max_radius, 0.0, -step)
    out = np.zeros(len(theta))
    for start in range(0, len(theta), 256):
        sl = slice(start, start + 256)
        pts = origin[sl, None] + ts[None, :, None] * direction[sl, None]
        sd = capsule_signed_distance(pts.reshape(-1, 3), a, b, radii=radii)[0].reshape(pts.shape[:2])
        inside = sd < gap
        hit = inside.any(1)
        first = inside.argmax(1)  # first sample (from outside) within gap of the body
        lo = ts[first]  # inside the gap
        hi = np.minimum(lo + step, max_radius)
        for _ in range(12):
            mid = 0.5 * (lo + hi)
            p = origin[sl] + mid[:, None] * direction[sl]
            d = capsule_signed_distance(p, a, b, radii=radii)[0]
            inner = d < gap
            lo, hi = np.where(inner, mid, lo), np.where(inner, hi, mid)
        out[sl] = np.where(hit, 0.5 * (lo + hi), 0.0)
    return out.reshape(shape)


def push_out_of_body(points: np.ndarray, gap: float, body: BodyModel, iterations: int = 4) -> np.ndarray:
    """``points`` moved along the body's normals until they are ``gap`` outside it."""
    a, b, radii = rest_body(body)
    for _ in range(iterations):
        d, n, _ = capsule_signed_distance(points, a, b, radii=radii)
        points = points + np.maximum(gap - d, 0.0)[:, None] * n
    return points


def shoulder_top(points: np.ndarray, gap: float, body: BodyModel) -> np.ndarray:
    """Height ``gap`` above the body's top surface straight above each point (x, z), head and neck
    left out: a strap passes beside them. (With them, a strap edge within the head's 9.5 cm radius
    of the midline found the top of the head: at 400 and 4,000 vertices, where the column nearest
    the strap line fell inside it, both straps looped over the head, 1.68 m high.)"""
    a, b, radii = rest_body(body)
    keep = [i for i, c in enumerate(body.capsules) if c.joint not in ("head", "neck")]
    a, b, radii = a[keep], b[keep], radii[keep]
    ys = np.arange(1.8, 0.9, -0.002)
    grid = np.repeat(points[:, None], len(ys), axis=1)
    grid[..., 1] = ys[None]
    d = capsule_signed_distance(grid.reshape(-1, 3), a, b, radii=radii)[0].reshape(grid.shape[:2])
    return ys[np.argmax(d < gap, axis=1)]
