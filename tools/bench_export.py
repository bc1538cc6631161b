"""Benchmark: export time and file size per format for a long animation.

Builds an out.h5 of ``--frames`` frames of the dress at ``--vertices`` vertices: the template
carried through a procedural clip (walk, dance, spin; the body's heading frame) with a swing that
varies over the skirt, so frames differ everywhere and are not linear in time. Then times each
export from reading out.h5 to the finished file, one run each:

    python tools/bench_export.py                        # 1,000 frames, 4,000 vertices, all formats
    python tools/bench_export.py --frames 300 --json

GLB is timed at the default 1 mm keyframe bound and at 0 (every frame); the number of keyframes it
kept is printed. The rendered GIF preview is timed too (every 2nd frame, two views).
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from hrr_garment.body.capsules import DEFAULT_BODY
from hrr_garment.data.animation_file import AnimationArrays, read_animation_h5, write_animation_h5
from hrr_garment.export.glb import write_glb
from hrr_garment.export.pointcache import write_obj_sequence, write_pc2_with_obj
from hrr_garment.export.usd import write_usd
from hrr_garment.export.video import PreviewStyle, write_preview
from hrr_garment.garment.templates import make_garment
from hrr_garment.motion.frame import from_body_frame, to_body_frame
from hrr_garment.motion.motion import Motion
from hrr_garment.motion.synth import synthesize


def long_motion(frames: int) -> Motion:
    kinds = ("walk", "dance", "spin", "walk_curve")
    parts, total, k = [], 0, 0
    while total < frames:
        m = synthesize(kinds[k % len(kinds)], 8.0, seed=k)
        parts.append(m)
        total += m.num_frames
        k += 1
    rot = np.concatenate([p.local_rotations for p in parts])[:frames]
    trans = np.concatenate([p.root_translation - p.root_translation[:1] * [1, 0, 1] for p in parts])[:frames]
    return Motion(rot, trans, source="bench")


def build_animation(path: Path, frames: int, vertices: int) -> Path:
    motion = long_motion(frames)
    dress = make_garment("dress", vertices)
    rest = to_body_frame(dress.vertices[None].astype(np.float64), motion.slice(0, 1))[0]
    t = np.arange(frames)[:, None, None] / 30.0
    below_hips = np.clip(1.0 - rest[None, :, 1:2], 0, None)
    swing = 0.08 * below_hips * np.sin(2 * np.pi * 0.9 * t + rest[None, :, 0:1] * 3 + rest[None, :, 2:3] * 2)
    local = rest[None] + swing * np.array([1.0, 0.15, 0.6])
    a, b = DEFAULT_BODY.pose_motion(motion)
    arrays = AnimationArrays(
        vertices=from_body_frame(local, motion),
        faces=dress.faces,
        joints=motion.joint_positions,
        retrieved=np.zeros(frames, np.uint8),
        entropy=np.zeros(frames),
        match=np.full((frames, 2), -1),
        capsules=np.stack([a, b], 2),
        radii=DEFAULT_BODY.radii,
    )
    return write_animation_h5(path, arrays, {"fps": 30.0, "garment": "dress", "source_motion": "bench"})


def _size(path: Path) -> int:
    return sum(p.stat().st_size for p in path.iterdir()) if path.is_dir() else path.stat().st_size


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--frames", type=int, default=1000)
    p.add_argument("--vertices", type=int, default=4000)
    p.add_argument("--no-preview", action="store_true")
    p.add_argument("--json", action="store_true")
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        source = build_animation(root / "out.h5", args.frames, args.vertices)
        anim = read_animation_h5(source)
        jobs = {
            "glb (1 mm keyframes)": (
                root / "a.glb",
                lambda o: write_glb(read_animation_h5(source), o, 0.001),
            ),
            "glb (every frame)": (root / "b.glb", lambda o: write_glb(read_animation_h5(source), o, 0.0)),
            "glb + body": (
                root / "c.glb",
                lambda o: write_glb(read_animation_h5(source), o, 0.001, with_body=True),
            ),
            "usd (usdc)": (root / "a.usdc", lambda o: write_usd(read_animation_h5(source), o)),
            "pc2 + obj": (root / "a.pc2", lambda o: write_pc2_with_obj(read_animation_h5(source), o)),
            "obj sequence": (
                root / "seq",
                lambda o: write_obj_sequence(read_animation_h5(source), o, progress=False),
            ),
        }
        if not args.no_preview:
            jobs["gif preview (every 2nd frame)"] = (
                root / "p.gif",
                lambda o: write_preview(
                    read_animation_h5(source), o, PreviewStyle(), every=2, progress=False
                ),
            )
        results = {
            "frames": anim.num_frames,
            "vertices": int(anim.vertices.shape[1]),
            "faces": int(len(anim.faces)),
            "out_h5_bytes": source.stat().st_size,
            "formats": {},
        }
        for name, (out, job) in jobs.items():
            t0 = time.perf_counter()
            value = job(out)
            seconds = time.perf_counter() - t0
            size = _size(out) + (out.with_suffix(".obj").stat().st_size if out.suffix == ".pc2" else 0)
            row = {"seconds": round(seconds, 2), "bytes": size}
            if hasattr(value, "keyframes"):
                row["keyframes"] = int(len(value.keyframes.frames))
                row["max_error_mm"] = round(1000 * value.keyframes.max_error, 3)
            results["formats"][name] = row
            if not args.json:
                extra = (
                    f", {row['keyframes']} keyframes (max error {row['max_error_mm']} mm)"
                    if "keyframes" in row
                    else ""
                )
                print(f"{name:32s} {seconds:6.2f} s  {size / 2**20:8.1f} MiB{extra}")
    if args.json:
        print(json.dumps(results, indent=1))
    else:
        print(
            f"({results['frames']} frames x {results['vertices']} vertices; out.h5 "
            f"{results['out_h5_bytes'] / 2**20:.1f} MiB)"
        )


if __name__ == "__main__":
    main()
