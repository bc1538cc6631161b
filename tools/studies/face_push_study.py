"""Skin seen through the cloth, and what keeping the skin's vertices out of the cloth's faces would
do about it: a model's cloth pushed out of a character's mesh as ``hrr-animate`` pushes it (each
garment vertex out of the skin), then, as an experiment, each face of the cloth that a skin vertex
comes through (or within ``--clearance`` of, along the skin's normal there) moved out by its
barycentric share of that depth (Bridson et al. 2002's point-face response, the skin's vertex
unmoving), a few rounds. Prints the skin seen through the cloth before and after
(``tools/render_glb.py``'s measure: the share of the cloth's pixels where the skin is drawn less
than 1 cm in front of it, three views, every ``--every``-th frame), how much of the cloth moved and
how far its edges stretched.

The skin is the one the character's GLB draws (``hrr-make``'s ``outputs/NAME_CLIP.glb`` or
``hrr-export --character``), the clip its dataset sequence:

    python tools/studies/face_push_study.py hrr_work/make-plain/model hrr_work/make-plain/dataset.h5 \\
        hrr_work/make-plain/outputs/plain_walk_002.glb walk_002
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parents[1]))
from render_glb import GARMENT, SKIN, drawn_view  # noqa: E402  (tools/ is not a package)

VIEWS = ("three-quarter", "front", "back")
REACH_M = 0.03  # a skin vertex farther than this from the cloth is not under it
SIDEWAYS_M = 0.01  # nor one whose nearest cloth point lies farther than this off its normal


def keep_skin_out_of_faces(cloth, faces, skin, skin_faces, clearance: float, rounds: int = 4) -> np.ndarray:
    """``cloth`` (V, 3) with each face a skin vertex comes through (or within ``clearance`` of, along
    the skin's normal) moved out along that normal by its barycentric share of the depth, the moves
    of a vertex from several faces averaged, ``rounds`` times."""
    from hrr_garment.body.mesh_distance import nearest_on_mesh, vertex_normals

    cloth = np.asarray(cloth, np.float64).copy()
    normals = vertex_normals(skin, skin_faces)
    for _ in range(rounds):
        distance, face, bary = nearest_on_mesh(skin, cloth, faces, candidates=16)
        offset = np.einsum("nk,nkc->nc", bary, cloth[faces[face]]) - skin
        along = (offset * normals).sum(1)
        sideways = np.linalg.norm(offset - along[:, None] * normals, axis=1)
        through = (distance < REACH_M) & (along < clearance) & (sideways < SIDEWAYS_M)
        if not through.any():
            break
        weights = bary[through]
        share = (clearance - along[through]) / (weights**2).sum(1)
        move, count = np.zeros_like(cloth), np.zeros(len(cloth))
        for k in range(3):
            corner = faces[face[through], k]
            np.add.at(move, corner, (share * weights[:, k])[:, None] * normals[through])
            np.add.at(count, corner, 1.0)
        cloth += move / np.maximum(count, 1.0)[:, None]
    return cloth


def skin_seen(cloth_frames, faces, skin_frames, skin_faces) -> np.ndarray:
    """The skin seen through the cloth on each frame and view (``render_glb``'s measure)."""
    from hrr_garment.export.ortho_render import PreviewMesh

    shares = []
    for cloth, skin in zip(cloth_frames, skin_frames):
        meshes = [PreviewMesh(cloth, faces.astype(np.int64), GARMENT), PreviewMesh(skin, skin_faces, SKIN)]
        shares += [drawn_view(meshes, view, 10.0, 420)[1] for view in VIEWS]
    return np.array(shares)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("model")
    p.add_argument("dataset", help="the dataset the clip's sequence is in (its motion)")
    p.add_argument("glb", help="the character's GLB of that clip (its skin, as drawn)")
    p.add_argument("sequence")
    p.add_argument("--clearance", type=float, default=0.003, help="metres the faces are kept off the skin")
    p.add_argument("--every", type=int, default=10, help="every N-th frame")
    args = p.parse_args()

    from hrr_garment.data.dataset import GarmentDataset
    from hrr_garment.export.glb_read import read_glb_character
    from hrr_garment.inference.animator import Animator

    animator = Animator.load(args.model)
    data = GarmentDataset(args.dataset)
    faces, edges = data.template.faces, data.template.edges()
    sequence = data.sequence(args.sequence)
    _, skin, skin_faces = read_glb_character(args.glb)
    pushed = animator.animate(sequence.motion).vertices  # the vertex push-out hrr-animate runs
    frames = range(0, min(len(skin), len(pushed)), args.every)
    before = [pushed[t].astype(np.float64) for t in frames]
    after = [
        keep_skin_out_of_faces(pushed[t], faces, skin[t].astype(np.float64), skin_faces, args.clearance)
        for t in frames
    ]
    # the push-out's own strain limit after the faces' push: what of it survives the limit
    from hrr_garment.inference.collision import PUSH_OUT
    from hrr_garment.inference.strain_limit import limit_push_strain

    at_rest = data.template.vertices if sequence.dressed is None else sequence.dressed.garment.vertices
    limited, repaired = limit_push_strain(
        np.stack(after),
        np.stack(before),
        animator.edge_limits.on_bodies(at_rest),  # the garment as it rests on the character
        PUSH_OUT.max_strain,
        slack=PUSH_OUT.stretch_slack,
    )
    for label, cloth in (
        ("the vertex push-out", before),
        (f"then the faces {1e3 * args.clearance:g} mm off", after),
        (f"then the strain limit (it acted on {100 * repaired.mean():.0f} % of the frames)", list(limited)),
    ):
        seen = skin_seen(cloth, faces, [skin[t] for t in frames], skin_faces)
        print(
            f"{args.sequence}, {label}: skin seen through the cloth {100 * seen.mean():.2f} % of its "
            f"pixels (worst {100 * seen.max():.2f} %)"
        )
    moved = np.concatenate([np.linalg.norm(a - b, axis=1) for a, b in zip(after, before)])
    length = lambda c: np.linalg.norm(c[edges[:, 0]] - c[edges[:, 1]], axis=1)  # noqa: E731
    stretch = np.concatenate([length(a) / length(b) for a, b in zip(after, before)])
    print(
        f"the faces' push moved {100 * (moved > 1e-3).mean():.2f} % of the cloth's vertices more than 1 mm "
        f"(at most {1e3 * moved.max():.1f} mm); edges stretched by it at most {stretch.max():.3f} x, p99 "
        f"{np.percentile(stretch, 99):.4f} x"
    )


if __name__ == "__main__":
    main()
