"""Preview images (PNG) of skeleton motion. Needs the ``preview`` extra (Pillow)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..io_utils import atomic_path
from ..motion.motion import Motion
from ..motion.rotations import rotation_about_y, yaw_of
from ..motion.skeleton import JOINT_NAMES, PARENTS


def _pil():
    try:
        from PIL import Image, ImageDraw
    except ImportError:
        raise ImportError("preview images need Pillow: pip install 'hrr_garment[preview]'") from None
    return Image, ImageDraw


_LEFT = (214, 69, 65)
_RIGHT = (52, 101, 164)
_CENTRE = (40, 40, 40)


def _colour(j: int) -> tuple[int, int, int]:
    name = JOINT_NAMES[j]
    return _LEFT if name.startswith("l_") else _RIGHT if name.startswith("r_") else _CENTRE


def render_skeleton_preview(rows: list[tuple[str, Motion]], path: str | Path, frames: int = 6, cell: int = 180) -> Path:
    """One row per motion: ``frames`` evenly spaced frames, each as a front and a side view.

    Views are in the character's heading frame at that frame (front: looking at its face; side:
    from its left), centred on the pelvis, with the ground line drawn; 1 m = ``cell * 0.45`` px.
    """
    Image, ImageDraw = _pil()
    width, height = frames * 2 * cell, len(rows) * (cell + 22)
    img = Image.new("RGB", (width, height), (250, 250, 247))
    draw = ImageDraw.Draw(img)
    scale = cell * 0.45
    for r, (label, motion) in enumerate(rows):
        top = r * (cell + 22)
        draw.text((4, top + 2), label, fill=(0, 0, 0))
        pos = motion.joint_positions
        heading = yaw_of(motion.global_rotations[:, 0])
        for k, t in enumerate(np.linspace(0, motion.num_frames - 1, frames).round().astype(int)):
            local = (pos[t] - pos[t, 0] * np.array([1, 0, 1])) @ rotation_about_y(heading[t])  # heading frame
            for v, (axis, sign) in enumerate(((0, -1.0), (2, 1.0))):  # front: -x to the right; side: +z to the right
                ox = (2 * k + v) * cell + cell / 2
                oy = top + 20 + cell * 0.95
                screen = np.stack([ox + sign * local[:, axis] * scale, oy - local[:, 1] * scale], 1)
                draw.line([(ox - cell * 0.4, oy), (ox + cell * 0.4, oy)], fill=(150, 150, 150), width=1)
                for j, p in enumerate(PARENTS):
                    if p >= 0:
                        draw.line([tuple(screen[p]), tuple(screen[j])], fill=_colour(j), width=3)
                draw.text((ox - cell / 2 + 3, top + 20), f"f{t} {'front' if v == 0 else 'side'}", fill=(90, 90, 90))
    path = Path(path)
    with atomic_path(path) as tmp:
        img.save(tmp, format="PNG")
    return path
