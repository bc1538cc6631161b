"""Render frames of a GLB that ``hrr-export`` wrote, as an engine plays it: the garment from its morph
targets and, where the file carries one (``--character``), the character's own mesh skinned by
glTF's rule from the file's skeleton, bind matrices and weights. Frames side by side in one PNG
(flat-shaded, orthographic; the ``preview`` extra). What it draws is read from the file alone, so
it shows what Blender, three.js or an engine will show, without them.

    python tools/render_glb.py hero_dress.glb -o hero.png --frames 0 10 20 --view three-quarter front

The frames are keyframe indices (``hrr-export --tolerance 0`` keeps every frame, so that each is the
clip's frame of that number). Prints, per frame, the garment's vertices inside the character's
mesh (more than 5 mm deep), the figure ``hrr-eval`` reports after the push-out, and the skin seen
through the garment: the share of the garment's pixels (drawn alone) where the character's mesh is
drawn in front of it. The two differ: a garment whose every vertex lies outside the mesh still shows
skin where the mesh bulges between its vertices through its faces.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

DEPTH_M = 0.005  # inside counts past 5 mm, as hrr-eval's "inside after the push-out"
# skin drawn in front of the cloth by less than this comes through it (an arm in front lies farther)
THROUGH_M = 0.01
GARMENT, SKIN, BACKGROUND = (70, 110, 200), (226, 190, 160), (255, 255, 255)


def arguments() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("glb", help="an hrr-export GLB (with --character: the character's mesh drawn too)")
    p.add_argument("-o", "--output", required=True, help="the PNG written")
    p.add_argument("--frames", type=int, nargs="+", default=[0], help="keyframe indices drawn, in order")
    p.add_argument(
        "--view",
        nargs="+",
        default=["three-quarter"],
        help="front, three-quarter, left, back, right: one row of the frames each",
    )
    p.add_argument("--elevation", type=float, default=10.0, help="camera elevation, degrees")
    p.add_argument("--size", type=int, default=420, help="pixels per frame (square)")
    return p.parse_args()


def inside_share(garment: np.ndarray, skin: np.ndarray, faces: np.ndarray) -> float:
    """The share of garment vertices (V, 3) more than DEPTH_M inside the mesh (skin, faces), as
    hrr-eval counts it (:func:`~hrr_garment.body.mesh_inside.inside_deeper_than`)."""
    from hrr_garment.body.mesh_inside import inside_deeper_than

    return float(inside_deeper_than(garment, skin, faces, depth=DEPTH_M).mean())


def skin_through(drawn, meshes: list, size: int) -> float:
    """The share of the garment's pixels (``meshes[0]`` drawn alone) where the skin (``meshes[1]``)
    is drawn in front of it by less than THROUGH_M: skin that comes through the cloth, not an arm
    in front of it (``drawn(meshes, depth)`` draws into the z-buffer ``depth``)."""
    cloth, skin = (np.full((size, size), -np.inf) for _ in range(2))
    drawn([meshes[0]], cloth)
    drawn([meshes[1]], skin)
    covered = np.isfinite(cloth)
    with np.errstate(invalid="ignore"):  # -inf - -inf where neither is drawn: not covered anyway
        through = covered & (skin > cloth) & (skin - cloth < THROUGH_M)
    return float(through.sum() / max(covered.sum(), 1))


def main() -> None:
    args = arguments()
    from hrr_garment.export.glb_read import read_glb_character, read_glb_keyframes
    from hrr_garment.export.ortho_render import PreviewMesh, pillow_modules

    Image, _ = pillow_modules()
    _, garment, garment_faces = read_glb_keyframes(args.glb)
    character = read_glb_character(args.glb)
    last = len(garment) - 1
    if any(not 0 <= f <= last for f in args.frames):
        raise SystemExit(f"{args.glb}: keyframes run 0..{last}; asked for {args.frames}")
    size = args.size
    sheet = Image.new("RGB", (size * len(args.frames), size * len(args.view)), BACKGROUND)
    for k, f in enumerate(args.frames):
        meshes = [PreviewMesh(garment[f], garment_faces.astype(np.int64), GARMENT)]
        note = ""
        if character is not None:
            _, skin, skin_faces = character
            meshes.append(PreviewMesh(skin[f], skin_faces, SKIN))
            inside = inside_share(garment[f], skin[f], skin_faces)
            note = f", {100 * inside:.2f} % of the garment inside the mesh"
        for row, view in enumerate(args.view):
            frame, through = drawn_view(meshes, view, args.elevation, size)
            sheet.paste(frame, (k * size, row * size))
            seen = "" if character is None else f"; {view}: skin seen through it on {100 * through:.2f} %"
            note += seen + (" of its pixels" if seen and row == len(args.view) - 1 else "")
        print(f"frame {f}{note}")
    output = Path(args.output)
    partial = output.with_name(output.name + ".partial.png")
    sheet.save(partial)
    partial.replace(output)
    print(f"wrote {output}")


def drawn_view(meshes: list, view: str, elevation: float, size: int):
    """The frame's meshes drawn from ``view`` (a PIL image of size x size, the meshes filling 90 %)
    and the skin seen through the garment there (:func:`skin_through`; 0 without a character)."""
    from hrr_garment.export.ortho_render import OrthoCamera, draw_meshes, pillow_modules

    Image, _ = pillow_modules()
    points = np.concatenate([m.vertices for m in meshes])
    lo, hi = points.min(0), points.max(0)
    camera = OrthoCamera.named(view, elevation, target=tuple((lo + hi) / 2))
    scale = 0.9 * size / max(float(np.ptp(camera.project(points)[:, :2], axis=0).max()), 1e-6)

    def drawn(shown, depth=None):
        blank = Image.new("RGB", (size, size), BACKGROUND)
        return draw_meshes(blank, shown, camera, (size / 2, size / 2), scale, depth)

    return drawn(meshes), (skin_through(drawn, meshes, size) if len(meshes) > 1 else 0.0)


if __name__ == "__main__":
    main()
