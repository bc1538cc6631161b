"""Preview images (PNG) of skeleton motion and of meshes (garment over body), and a built dataset's
preview. Needs the ``preview`` extra (Pillow); the meshes are drawn by :mod:`.ortho_render`."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..io_utils import atomic_path
from ..motion.frame import to_body_frame
from ..motion.motion import Motion
from ..motion.skeleton import JOINT_NAMES, PARENTS
from .ortho_render import OrthoCamera, PreviewMesh, draw_meshes, pillow_modules

_LEFT = (214, 69, 65)
_RIGHT = (52, 101, 164)
_CENTRE = (40, 40, 40)


def _colour(j: int) -> tuple[int, int, int]:
    name = JOINT_NAMES[j]
    return _LEFT if name.startswith("l_") else _RIGHT if name.startswith("r_") else _CENTRE


def render_skeleton_preview(
    rows: list[tuple[str, Motion]], path: str | Path, frames: int = 6, cell: int = 180
) -> Path:
    """One row per motion: ``frames`` evenly spaced frames, each as a front and a side view.

    Views are in the character's ground-level body frame at that frame (front: looking at its face; side:
    from its left), centred on the pelvis, with the ground line drawn; 1 m = ``cell * 0.45`` px.
    """
    Image, ImageDraw = pillow_modules()
    width, height = frames * 2 * cell, len(rows) * (cell + 22)
    img = Image.new("RGB", (width, height), (250, 250, 247))
    draw = ImageDraw.Draw(img)
    scale = cell * 0.45
    for r, (label, motion) in enumerate(rows):
        top = r * (cell + 22)
        draw.text((4, top + 2), label, fill=(0, 0, 0))
        joints = to_body_frame(motion.joint_positions, motion, ground=True)
        for k, t in enumerate(np.linspace(0, motion.num_frames - 1, frames).round().astype(int)):
            local = joints[t]
            for v, (axis, sign) in enumerate(
                ((0, 1.0), (2, -1.0))
            ):  # front: its left on our right; side: from its left
                ox = (2 * k + v) * cell + cell / 2
                oy = top + 20 + cell * 0.95
                screen = np.stack([ox + sign * local[:, axis] * scale, oy - local[:, 1] * scale], 1)
                draw.line([(ox - cell * 0.4, oy), (ox + cell * 0.4, oy)], fill=(150, 150, 150), width=1)
                for j, p in enumerate(PARENTS):
                    if p >= 0:
                        draw.line([tuple(screen[p]), tuple(screen[j])], fill=_colour(j), width=3)
                draw.text(
                    (ox - cell / 2 + 3, top + 20), f"f{t} {'front' if v == 0 else 'side'}", fill=(90, 90, 90)
                )
    path = Path(path)
    with atomic_path(path) as tmp:
        img.save(tmp, format="PNG")
    return path


def render_mesh_preview(
    rows: list[tuple[str, list[list[PreviewMesh]]]],
    path: str | Path,
    cell: int = 220,
    views: tuple[str, ...] = ("front", "side"),
    metres: float = 2.0,
) -> Path:
    """A grid of flat-shaded orthographic renders: one row per label, each frame in every view.

    ``metres`` is the height of world space a cell shows (feet at the bottom).
    """
    Image, ImageDraw = pillow_modules()
    columns = max(len(frames) for _, frames in rows) * len(views)
    img = Image.new("RGB", (columns * cell, len(rows) * (cell + 20)), (250, 250, 247))
    draw = ImageDraw.Draw(img)
    scale = cell / metres
    for r, (label, frames) in enumerate(rows):
        top = r * (cell + 20)
        draw.text((4, top + 3), label, fill=(0, 0, 0))
        for k, meshes in enumerate(frames):
            for v, view in enumerate(views):
                left = (k * len(views) + v) * cell
                tile = draw_meshes(
                    Image.new("RGB", (cell, cell), (250, 250, 247)),
                    meshes,
                    OrthoCamera.named(view),
                    centre=(cell / 2, cell * 0.97),
                    scale=scale,
                )
                img.paste(tile, (left, top + 20))
                draw.text((left + 3, top + cell + 4), view, fill=(120, 120, 120))
    path = Path(path)
    with atomic_path(path) as tmp:
        img.save(tmp, format="PNG")
    return path


def render_sequence_preview(
    rows: list[tuple[str, np.ndarray, np.ndarray, Motion]], path: str | Path, frames: int = 4, cell: int = 220
) -> Path:
    """Garment over body for a few evenly spaced frames of each (label, vertices (T, V, 3), faces,
    motion) row, shown in the ground-level body frame (front and side views)."""
    return render_mesh_preview(sequence_rows(rows, frames), path, cell=cell)


def sequence_rows(rows: list[tuple], frames: int = 4) -> list:
    """:func:`render_sequence_preview`'s rows of meshes: (label, vertices, faces, motion), and the
    body it was simulated on (a :class:`~hrr_garment.body.body_file.BodyRecord`) as a fifth item
    where it is not the mannequin: drawn as its own mesh where it has one (a parametric shape, with
    the ``bodies`` extra installed; a fitted character's, from its body.json), else as its capsules."""
    from ..body.capsules import DEFAULT_BODY, body_mesh
    from ..body.skinned_body import visible_body

    grid = []
    for label, vertices, faces, motion, *on in rows:
        body = on[0].body if on else DEFAULT_BODY
        visible = visible_body(on[0]) if on else None
        a, b = body.pose_motion(motion)
        cells = []
        for t in np.linspace(0, len(vertices) - 1, frames).round().astype(int):
            pose = motion.slice(t, t + 1)
            garment = to_body_frame(vertices[t : t + 1].astype(np.float64), pose, ground=True)[0]
            if visible is not None:
                bv = to_body_frame(
                    visible.pose(motion.global_rotations[t : t + 1], motion.joint_positions[t : t + 1]),
                    pose,
                    ground=True,
                )[0]
                bf = visible.faces
            else:
                ends = to_body_frame(np.stack([a[t], b[t]])[None].reshape(1, -1, 3), pose, ground=True)[0]
                bv, bf = body_mesh(ends[: len(a[t])], ends[len(a[t]) :], body.radii, segments=12, rings=6)
            cells.append([PreviewMesh(bv, bf, (205, 195, 185)), PreviewMesh(garment, faces, (70, 110, 200))])
        grid.append((f"{label} (frames {0}-{len(vertices) - 1})", cells))
    return grid


def write_dataset_preview(
    records: list, garment, path: Path, frames: int = 4, bodies: dict | None = None
) -> Path | None:
    """Front and side views of a walk and a spin (or the first two sequences) of a built
    dataset (``SequenceRecord``s of a ``GarmentMesh``), in the ground-level body frame; with
    ``bodies`` (name -> :class:`~hrr_garment.garment.dressing.DressedBody`), each on its own body, and
    the garment at rest on the shortest and the tallest of them (a parametric body drawn as its own
    mesh). None when Pillow (the ``preview`` extra) is missing."""
    bodies = bodies or {}
    chosen = []
    for kind in ("walk", "spin"):
        chosen += [r for r in records if r.info.get("kind") == kind][:1]
    chosen = chosen or records[:2]
    used = sorted(
        {r.body_name for r in records if r.body_name in bodies}, key=lambda n: bodies[n].record.stature
    )
    extremes = [used[0], used[-1]] if len(used) > 1 else used
    chosen += [
        next(r for r in records if r.body_name == name)
        for name in extremes
        if not any(c.body_name == name for c in chosen)
    ]
    try:
        rest = [
            (
                "the template on the rest body; attached vertices (they follow the body) in orange",
                [template_meshes(garment)]
                + [template_meshes(bodies[n].garment, body=bodies[n].record) for n in extremes],
            )
        ]
        rows = [
            (
                f"{r.name} on {r.body_name}" if r.body_name in bodies else r.name,
                r.garment,
                garment.faces,
                r.motion,
                *([bodies[r.body_name].record] if r.body_name in bodies else []),
            )
            for r in chosen
        ]
        return render_mesh_preview(rest + sequence_rows(rows, frames), path)
    except ImportError:
        return None


def template_meshes(garment, marker: float = 0.015, body=None) -> list[PreviewMesh]:
    """The body (a :class:`~hrr_garment.body.body_file.BodyRecord`; default the mannequin) in its
    rest pose, as its own mesh where it has one (an anny body's, a fitted character's), else its
    capsules; the garment's
    template on it and a small octahedron on every attached vertex: where a fitted garment sits,
    and what follows the body."""
    from ..body.capsules import DEFAULT_BODY, body_mesh
    from ..body.skinned_body import visible_body

    capsules = body.body if body is not None else DEFAULT_BODY
    visible = visible_body(body) if body is not None else None
    if visible is not None:  # T-pose: every joint's rotation the identity, the pelvis over the origin
        rest = capsules.rest_joints()[None]
        bv, bf = visible.pose(np.broadcast_to(np.eye(3), (1, 22, 3, 3)), rest)[0], visible.faces
    else:
        a, b = capsules.rest_pose()
        bv, bf = body_mesh(a, b, capsules.radii, segments=12, rings=6)
    tips = np.concatenate([np.eye(3), -np.eye(3)]) * marker
    octahedron = np.array(
        [[0, 1, 2], [1, 3, 2], [3, 4, 2], [4, 0, 2], [1, 0, 5], [3, 1, 5], [4, 3, 5], [0, 4, 5]]
    )
    corners = tips[[0, 1, 3, 4, 2, 5]]  # +x, +y, -x, -y around the z axis, then +z, -z
    attached = garment.vertices[garment.attached].astype(np.float64)
    mv = (attached[:, None] + corners[None]).reshape(-1, 3)
    mf = (octahedron[None] + 6 * np.arange(len(attached))[:, None, None]).reshape(-1, 3)
    return [
        PreviewMesh(bv, bf, (205, 195, 185)),
        PreviewMesh(garment.vertices.astype(np.float64), garment.faces, (70, 110, 200)),
        PreviewMesh(mv, mf, (235, 130, 30)),
    ]
