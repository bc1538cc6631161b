"""Render frames of a GLB that ``hrr-export`` wrote, as an engine plays it: the garment from its morph
targets and, where the file carries one (``--character``), the character's own mesh skinned by
glTF's rule from the file's skeleton, bind matrices and weights. Frames side by side in one PNG
(flat-shaded, orthographic; the ``preview`` extra). What it draws is read from the file alone, so
it shows what Blender, three.js or an engine will show, without them.

    python tools/render_glb.py hero_dress.glb -o hero.png --frames 0 10 20 --view three-quarter

The frames are keyframe indices (``hrr-export --tolerance 0`` keeps every frame, so that each is the
clip's frame of that number). Prints, per frame, the garment's vertices inside the character's
mesh (more than 5 mm deep), the figure ``hrr-eval`` reports after the push-out.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

DEPTH_M = 0.005  # inside counts past 5 mm, as hrr-eval's "inside after the push-out"
GARMENT, SKIN = (70, 110, 200), (226, 190, 160)


def arguments() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("glb", help="an hrr-export GLB (with --character: the character's mesh drawn too)")
    p.add_argument("-o", "--output", required=True, help="the PNG written")
    p.add_argument("--frames", type=int, nargs="+", default=[0], help="keyframe indices drawn, in order")
    p.add_argument("--view", default="three-quarter", help="front, three-quarter, left, back, right")
    p.add_argument("--elevation", type=float, default=10.0, help="camera elevation, degrees")
    p.add_argument("--size", type=int, default=420, help="pixels per frame (square)")
    return p.parse_args()


def inside_share(garment: np.ndarray, skin: np.ndarray, faces: np.ndarray) -> float:
    """The share of garment vertices (V, 3) more than DEPTH_M inside the mesh (skin, faces), as
    hrr-eval counts it (:func:`~hrr_garment.body.mesh_inside.inside_deeper_than`)."""
    from hrr_garment.body.mesh_inside import inside_deeper_than

    return float(inside_deeper_than(garment, skin, faces, depth=DEPTH_M).mean())


def main() -> None:
    args = arguments()
    from hrr_garment.export.glb_read import read_glb_character, read_glb_keyframes
    from hrr_garment.export.ortho_render import OrthoCamera, PreviewMesh, draw_meshes, pillow_modules

    Image, _ = pillow_modules()
    _, garment, garment_faces = read_glb_keyframes(args.glb)
    character = read_glb_character(args.glb)
    last = len(garment) - 1
    if any(not 0 <= f <= last for f in args.frames):
        raise SystemExit(f"{args.glb}: keyframes run 0..{last}; asked for {args.frames}")
    size = args.size
    strip = Image.new("RGB", (size * len(args.frames), size), (255, 255, 255))
    for k, f in enumerate(args.frames):
        meshes = [PreviewMesh(garment[f], garment_faces.astype(np.int64), GARMENT)]
        note = ""
        if character is not None:
            _, skin, skin_faces = character
            meshes.append(PreviewMesh(skin[f], skin_faces, SKIN))
            inside = inside_share(garment[f], skin[f], skin_faces)
            note = f", {100 * inside:.2f} % of the garment inside the mesh"
        points = np.concatenate([m.vertices for m in meshes])
        lo, hi = points.min(0), points.max(0)
        camera = OrthoCamera.named(args.view, args.elevation, target=tuple((lo + hi) / 2))
        scale = 0.9 * size / max(float(np.ptp(camera.project(points)[:, :2], axis=0).max()), 1e-6)
        frame = draw_meshes(
            Image.new("RGB", (size, size), (255, 255, 255)), meshes, camera, (size / 2, size / 2), scale
        )
        strip.paste(frame, (k * size, 0))
        print(f"frame {f}{note}")
    output = Path(args.output)
    partial = output.with_name(output.name + ".partial.png")
    strip.save(partial)
    partial.replace(output)
    print(f"wrote {output}")


if __name__ == "__main__":
    main()
