"""A game-loop style use of the streaming API: a few dancers, one call per frame for all of them.

    python examples/game_loop.py                                   # workspace dress model, procedural dance
    python examples/game_loop.py --motion ../shared/data/mocap/cmu/02_01.bvh \\
        --model hrr_work/models/dress-quick
    python examples/game_loop.py --characters 8 --headless --frames-dir hrr_work/game_frames

A game takes each character's pose from its animation system as arrays: local joint rotations
(quaternions, x y z w) and a root position. Here the poses come from a motion file (or a
procedural clip): character i plays it from its own start frame, standing in a row, and every
frame all the characters' arrays go to ``crowd.push`` in one call, as they would arrive. With a
display and Tk, a window shows the garments over the bodies; without one (or with --headless)
every --save-every-th frame is written as PNG. At the end it prints the latency of ``crowd.push``
(the garment step a game would pay for all its dancers) and of drawing.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

from hrr_garment import Animator, load_motion
from hrr_garment.body.capsules import DEFAULT_BODY, body_mesh
from hrr_garment.export.ortho_render import PreviewMesh
from hrr_garment.export.video import BODY, GARMENT, PreviewStyle, render_scene
from hrr_garment.motion.rotations import matrix_to_quat
from hrr_garment.motion.synth import synthesize
from hrr_garment.native import PRECISIONS


class Window:
    """A Tk window showing PIL images; ``closed`` turns true when the user closes it."""

    def __init__(self, title: str):
        import tkinter

        from PIL import ImageTk

        self._tk, self._imagetk = tkinter.Tk(), ImageTk
        self._tk.title(title)
        self._label = tkinter.Label(self._tk)
        self._label.pack()
        self.closed = False
        self._tk.protocol("WM_DELETE_WINDOW", self._close)

    def _close(self):
        self.closed = True

    def show(self, image) -> None:
        photo = self._imagetk.PhotoImage(image)
        self._label.configure(image=photo)
        self._label.image = photo  # Tk keeps no reference of its own
        self._tk.update()


def open_window(title: str) -> Window | None:
    """A window when a display and Tk are available, else None (headless)."""
    if not (
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY") or sys.platform in ("win32", "darwin")
    ):
        return None
    try:
        return Window(title)
    except Exception as exc:  # no Tk, or the display refused the connection
        print(f"no window ({exc}); running headless")
        return None


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--model", default="dress", help="model directory or garment name (default: dress)")
    p.add_argument(
        "--motion", type=Path, default=None, help="BVH/npz to take poses from (default: procedural dance)"
    )
    p.add_argument("--seconds", type=float, default=6.0, help="length of the procedural clip")
    p.add_argument("--characters", type=int, default=3, help="dancers streamed together (default 3)")
    p.add_argument("--headless", action="store_true", help="never open a window")
    p.add_argument(
        "--frames-dir", type=Path, default=Path("hrr_work/game_frames"), help="PNG frames when headless"
    )
    p.add_argument("--save-every", type=int, default=10, help="headless: save every N-th frame")
    p.add_argument("--realtime", action="store_true", help="wait so frames are shown at the clip's rate")
    p.add_argument("--size", type=int, default=320, help="pixels per view")
    p.add_argument(
        "--precision",
        choices=PRECISIONS,
        default="float32",
        help="the mesh decoder's arithmetic: bfloat16 (AMX, recent Intel Xeons) for large crowds",
    )
    return p


def main(argv=None) -> int:
    """Run the game loop over a clip; returns the exit status."""
    args = _parser().parse_args(argv)

    animator = Animator.load(args.model, precision=args.precision)
    motion = load_motion(args.motion) if args.motion else synthesize("dance", args.seconds, seed=3)
    crowd = animator.crowd()  # the model's calibrated mode (auto), its tau, collision push-out
    n = max(1, args.characters)
    # what the game's animation system holds for each character: local rotations and its root
    quats = matrix_to_quat(motion.local_rotations.astype(np.float64))[..., [1, 2, 3, 0]]  # (x, y, z, w)
    start_frame = (np.arange(n) * motion.num_frames) // n
    place = np.stack([1.2 * (np.arange(n) - (n - 1) / 2), np.zeros(n), np.zeros(n)], 1)
    faces = animator.bundle.template.faces
    style = PreviewStyle(views=("front", "three-quarter"), size=args.size, supersample=1)
    window = None if args.headless else open_window(f"hrr_garment: {animator.bundle.garment} x {n}")
    if window is None:
        args.frames_dir.mkdir(parents=True, exist_ok=True)
    ends_a, ends_b = DEFAULT_BODY.pose_motion(motion)
    push_ms, draw_ms = [], []
    start = time.perf_counter()
    for t in range(motion.num_frames):
        frame = (start_frame + t) % motion.num_frames  # each character's frame of the clip this tick
        t0 = time.perf_counter()
        vertices = crowd.push(
            quats[frame], motion.root_translation[frame] + place, keys=range(n)
        )  # (n, V, 3)
        push_ms.append(1000 * (time.perf_counter() - t0))
        if window is None and t % args.save_every:
            continue
        t0 = time.perf_counter()
        meshes = []
        for i, f in enumerate(frame):
            body_v, body_f = body_mesh(ends_a[f] + place[i], ends_b[f] + place[i], DEFAULT_BODY.radii, 12, 6)
            meshes += [
                PreviewMesh(body_v, body_f, BODY),
                PreviewMesh(vertices[i].astype(np.float64), faces, GARMENT),
            ]
        centre = motion.root_translation[frame].mean(0) + place.mean(0)
        image = render_scene(
            meshes, (centre[0], 0.0, centre[2]), style, f"frame {t}  push {push_ms[-1]:.1f} ms"
        )
        if window is not None:
            window.show(image)
            if window.closed:
                break
        else:
            image.save(args.frames_dir / f"frame_{t:05d}.png")
        draw_ms.append(1000 * (time.perf_counter() - t0))
        if args.realtime:
            time.sleep(max(0.0, start + (t + 1) / motion.fps - time.perf_counter()))
    p50, p99 = np.percentile(push_ms, [50, 99])
    print(
        f"{len(push_ms)} frames of {n} x {animator.bundle.garment} ({vertices.shape[1]} vertices): "
        f"crowd.push p50 {p50:.1f} ms, p99 {p99:.1f} ms for all {n}; drawing {np.mean(draw_ms):.0f} ms per "
        "shown frame" + ("" if window else f"; frames in {args.frames_dir}")
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
