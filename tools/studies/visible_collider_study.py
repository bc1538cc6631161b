"""The colliders against the body the viewer sees: how near the inverse-skinning collider's, the
per-joint SDF grids' and the capsules' signed distances are to the exact distance to the
linear-blend-skinned mesh (issue 82).

For each anny body and clip, the frames where the body is most bent (the largest sum of its joints'
turns from the rest pose) are posed by linear blend skinning (hrr_garment.body.skinned_body); points
are spread over the posed mesh by area and moved along its normal by -20, -5, 0, +5 and +20 mm. Each
point's exact signed distance (nearest face, sign by winding number) is compared with the
inverse-skinning collider's (hrr_garment.body.skin_collider), the grids' (hrr_garment.body.bone_sdf)
and the capsules' (hrr_garment.body.capsules), on the same points: the error's mean, p95, p99 and
max and the share over 20 mm, at joints (the point's largest skin weight under 0.9) and along bones;
of the points more than 3 mm inside the mesh, the share a collider calls outside (cloth it would
leave inside), and of those more than 3 mm outside, the share it calls inside; the same shares of
points anywhere about the body (its posed box widened by 50 cm) more than 3 cm from the skin; and
the numpy queries' time for 4,156 points (one dress) on one core. Needs the bodies extra (anny;
its cache under HRR_HOME). About five minutes on one core.

    python tools/studies/visible_collider_study.py ../shared/data/mocap/cmu/*.bvh --synth dance jump
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

SHAPES = {"average": {}, "heavy": {"weight": 0.9, "gender": 0.0}}
OFFSETS_M = (-0.02, -0.005, 0.0, 0.005, 0.02)  # along the posed mesh's normal
JOINT_WEIGHT = 0.9  # a point whose largest skin weight is under this lies at a joint
CLOTH_VERTICES = 4156  # the run-time push-out's dress, timed
CLEAR_M = 0.003  # a point counts as inside or outside from this far from the skin
AROUND_M = 0.5  # the points about the body: in its posed box widened by this
FAR_M = 0.03  # of those, the ones this far from the skin (past the push-out's band)


def bent_frames(motion, count: int) -> list[int]:
    """The ``count`` frames (at least a second apart) where the joints turn farthest from rest."""
    local = motion.local_rotations[:, 1:]
    angle = np.arccos(np.clip((np.trace(local, axis1=-2, axis2=-1) - 1.0) / 2.0, -1.0, 1.0)).sum(1)
    chosen: list[int] = []
    for t in np.argsort(-angle):
        if all(abs(int(t) - c) >= motion.fps for c in chosen):
            chosen.append(int(t))
        if len(chosen) == count:
            break
    return chosen


def surface_points(vertices: np.ndarray, faces: np.ndarray, weights: np.ndarray, count: int, seed: int):
    """``count`` points on the mesh by area, each moved along the normal by one of OFFSETS_M, with its
    offset and its largest skin weight (interpolated)."""
    from hrr_garment.body.mesh_distance import surface_samples, vertex_normals

    rng = np.random.default_rng(seed)
    face, bary = surface_samples(vertices, faces, count, rng=rng)
    corners = faces[face]
    normal = np.einsum("nk,nkc->nc", bary, vertex_normals(vertices, faces)[corners])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    offset = rng.choice(OFFSETS_M, count)
    points = np.einsum("nk,nkc->nc", bary, vertices[corners]) + offset[:, None] * normal
    return points, offset, np.einsum("nk,nkj->nj", bary, weights[corners]).max(1)


def measure(name: str, shape: dict, clips: list, args) -> list[dict]:
    """Every chosen frame of every clip on one body: the exact and both colliders' distances."""
    from hrr_garment.body.body_file import record_of
    from hrr_garment.body.bone_sdf import bone_sdf_collider
    from hrr_garment.body.capsules import capsule_signed_distance
    from hrr_garment.body.mesh_distance import mesh_signed_distance
    from hrr_garment.body.parametric import BodyShape, parametric_body
    from hrr_garment.body.retarget import motion_on_body
    from hrr_garment.body.skin_collider import skin_collider
    from hrr_garment.body.skinned_body import visible_body

    record = record_of(parametric_body(BodyShape(**shape)))
    visible = visible_body(record)
    t0 = time.perf_counter()
    grids = bone_sdf_collider(visible)
    print(f"{name}: {len(grids.values):,} grid nodes built in {time.perf_counter() - t0:.1f} s")
    t0 = time.perf_counter()
    skin = skin_collider(visible)
    print(
        f"{name}: inverse-skinning grid of {len(skin.distance):,} nodes, {skin.nbytes / 1e6:.1f} MB, "
        f"built in {time.perf_counter() - t0:.1f} s"
    )
    rows = []
    for clip_name, clip in clips:
        motion = motion_on_body(clip, record)
        for t in bent_frames(motion, args.frames):
            rot, pos = motion.global_rotations[t], motion.joint_positions[t]
            posed = visible.pose(rot[None], pos[None])[0]
            points, offset, weight = surface_points(posed, visible.faces, visible.weights, args.points, t)
            a, b = record.body.pose(rot[None], pos[None])
            timing = surface_points(posed, visible.faces, visible.weights, CLOTH_VERTICES, t + 1)[0]
            seconds = {}
            for key, collider in (("grids", grids), ("skin", skin)):
                t0 = time.perf_counter()
                collider.query(timing, rot, pos)
                seconds[key] = time.perf_counter() - t0
            # and points anywhere about the body, up to half a metre off its box (the band's outside)
            rng = np.random.default_rng(t)
            around = rng.uniform(posed.min(0) - AROUND_M, posed.max(0) + AROUND_M, (args.points, 3))
            row = {"body": name, "clip": clip_name, "frame": t, "offset": offset, "seconds": seconds}
            for key, p in (("", points), ("around_", around)):
                row[key + "exact"] = mesh_signed_distance(p, posed, visible.faces)
                row[key + "skin"] = skin.query(p, rot, pos)[0]
                row[key + "grids"] = grids.query(p, rot, pos)[0]
                row[key + "capsules"] = capsule_signed_distance(p, a[0], b[0], radii=record.body.radii)[0]
            rows.append(row | {"at_joint": weight < JOINT_WEIGHT})
    return rows


def far_sides(rows: list[dict], collider: str) -> dict:
    """Of the points about the body more than FAR_M from its skin, the shares on the wrong side."""
    exact = np.concatenate([r["around_exact"] for r in rows])
    got = np.concatenate([r["around_" + collider] for r in rows])
    inside, outside = exact < -FAR_M, exact > FAR_M
    return {
        "points": int((inside | outside).sum()),
        "inside_called_outside": float((got[inside] > 0).mean()),
        "outside_called_inside": float((got[outside] < 0).mean()),
    }


def summarise(rows: list[dict], collider: str, where: str) -> dict:
    """Error statistics in mm and the misclassified shares, pooled over ``rows``."""
    exact = np.concatenate([r["exact"] for r in rows])
    got = np.concatenate([r[collider] for r in rows])
    at_joint = np.concatenate([r["at_joint"] for r in rows])
    keep = {"all": np.ones_like(at_joint), "joints": at_joint, "bones": ~at_joint}[where]
    exact, got = exact[keep], got[keep]
    error = np.abs(got - exact) * 1000
    # which side: of the points clear of the skin (on it, the side is a matter of rounding)
    inside, outside = exact < -CLEAR_M, exact > CLEAR_M
    return {
        "points": int(keep.sum()),
        "mean_mm": float(error.mean()),
        "p95_mm": float(np.percentile(error, 95)),
        "p99_mm": float(np.percentile(error, 99)),
        "max_mm": float(error.max()),
        "over_20mm": float((error > 20).mean()),
        "inside_called_outside": float((got[inside] > 0).mean()),
        "outside_called_inside": float((got[outside] < 0).mean()),
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("clips", nargs="*", type=Path, help="motion files (BVH, glTF, ...)")
    p.add_argument("--synth", nargs="*", default=["dance", "jump"], help="procedural clips beside them")
    p.add_argument("--bodies", nargs="+", default=list(SHAPES), choices=list(SHAPES))
    p.add_argument("--frames", type=int, default=2, help="the most bent frames of each clip")
    p.add_argument("--points", type=int, default=1500, help="points measured a frame")
    p.add_argument("--json", type=Path, default=None, help="also write the summary here")
    args = p.parse_args()
    from hrr_garment.motion.io import load_motion
    from hrr_garment.motion.synth import synthesize

    clips = [(c.stem, load_motion(c)) for c in args.clips]
    clips += [(f"synth:{k}", synthesize(k, 6.0)) for k in args.synth]
    rows = [row for b in args.bodies for row in measure(b, SHAPES[b], clips, args)]
    summary = {
        f"{collider}/{where}": summarise(rows, collider, where)
        for collider in ("skin", "grids", "capsules")
        for where in ("all", "joints", "bones")
    }
    far = {collider: far_sides(rows, collider) for collider in ("skin", "grids", "capsules")}
    ms = {k: 1000 * float(np.median([r["seconds"][k] for r in rows])) for k in ("skin", "grids")}
    if args.json:
        args.json.write_text(json.dumps({"summary": summary, "far": far, "query_ms": ms}, indent=1))
    print(f"{len(rows)} frames ({', '.join(args.bodies)}; {', '.join(n for n, _ in clips)})")
    print(
        "| collider | where | points | error mean / p95 / p99 / max (mm) | error over 20 mm "
        "| inside called outside | outside called inside |"
    )
    print("|---|---|---:|---:|---:|---:|---:|")
    for key, s in summary.items():
        collider, where = key.split("/")
        print(
            f"| {collider} | {where} | {s['points']} | "
            f"{s['mean_mm']:.1f} / {s['p95_mm']:.1f} / {s['p99_mm']:.1f} / {s['max_mm']:.0f} | "
            f"{100 * s['over_20mm']:.1f} % | "
            f"{100 * s['inside_called_outside']:.1f} % | {100 * s['outside_called_inside']:.1f} % |"
        )
    for key, f in far.items():
        print(
            f"{key}: of {f['points']} points about the body more than {FAR_M * 1000:.0f} mm from the skin, "
            f"inside called outside {100 * f['inside_called_outside']:.2f} %, "
            f"outside called inside {100 * f['outside_called_inside']:.2f} %"
        )
    for key, value in ms.items():
        print(f"{key}: {CLOTH_VERTICES} points, numpy, one core: {value:.0f} ms a query (median over frames)")


if __name__ == "__main__":
    main()
