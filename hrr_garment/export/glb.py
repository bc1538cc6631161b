"""GLB (binary glTF 2.0) export: the garment as a morph-target animation, optionally the body.

The garment is one mesh whose base is frame 0 and which has one morph target per later keyframe
(the target holds that keyframe minus the base). Its weights are animated with LINEAR
interpolation: at keyframe k the weights are one-hot on k, so between two keyframes the mesh is
their linear interpolation, and keyframes (chosen by :mod:`.keyframes`) keep every frame within
the stated tolerance. glTF is Y up in metres, which is out.h5's convention, so no conversion.

Normals (unless ``normals=False``): the base carries frame 0's vertex normals and each target its
keyframe's normals minus them, so an engine that morphs normals (three.js, Blender, Unity) shades
the cloth smoothly; without them three.js shades every triangle flat. Renderers normalise the
blended normal, so between keyframes it is the normalised blend of the two keyframes' normals.
They add about as many bytes as the positions.

The body is a node per capsule (a rigid mesh) with animated translation and rotation, or, for a
character file, the character's own skinned mesh on a skeleton playing the clip (:mod:`.character`).
Needs the ``export`` extra (pygltflib). Its building blocks: :mod:`.glb_blob`; reading it back:
:mod:`.glb_read`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..data.animation_file import AnimationFile
from ..garment.mesh import vertex_normals
from ..io_utils import atomic_write_bytes
from .character import SkinnedCharacter, add_character
from .glb_blob import ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER, GlbBlob, pygltflib_module
from .glb_body import add_capsule_body
from .keyframes import Keyframes, select_keyframes


@dataclass(frozen=True)
class GlbReport:
    """What write_glb wrote: the path, the keyframes and the size."""

    path: Path
    keyframes: Keyframes
    bytes: int


def write_glb(
    anim: AnimationFile,
    path: str | Path,
    tolerance: float = 0.001,
    with_body: bool = False,
    normals: bool = True,
    character: SkinnedCharacter | None = None,
) -> GlbReport:
    """Write ``anim`` as GLB. ``tolerance`` (metres) bounds the keyframe reduction; 0 keeps every
    frame. ``normals``: vertex normals on the base and the targets (see the module docstring).
    ``with_body``: the collision capsules too; ``character``: the character's own skinned mesh,
    posed by the clip (:func:`.character.skinned_character`)."""
    gl = pygltflib_module()
    path = Path(path)
    keys = select_keyframes(anim.vertices, tolerance)
    verts = anim.vertices.astype(np.float32)
    base = verts[0]
    deltas = verts[keys.frames[1:]] - base  # (K-1, V, 3)
    blob = GlbBlob(gl)
    position = blob.stored(base, "VEC3", ARRAY_BUFFER, bounds=True)
    indices = blob.stored(anim.faces.astype(np.uint32).ravel(), "SCALAR", ELEMENT_ARRAY_BUFFER)
    normal, normal_deltas = None, None
    if normals:
        keyframe_normals = vertex_normals(verts[keys.frames], anim.faces).astype(np.float32)  # (K, V, 3)
        normal = blob.stored(keyframe_normals[0], "VEC3", ARRAY_BUFFER)
        normal_deltas = keyframe_normals[1:] - keyframe_normals[0]
    targets = []
    if len(deltas):
        view = blob.view(deltas, ARRAY_BUFFER, stride=12)
        normal_view = None if normal_deltas is None else blob.view(normal_deltas, ARRAY_BUFFER, stride=12)
        for k, delta in enumerate(deltas):
            target = {"POSITION": blob.accessor(view, delta, "VEC3", True, k * delta.nbytes)}
            if normal_view is not None:
                target["NORMAL"] = blob.accessor(
                    normal_view, normal_deltas[k], "VEC3", False, k * delta.nbytes
                )
            targets.append(gl.Attributes(**target))
    materials = [
        gl.Material(
            name="garment",
            doubleSided=True,
            pbrMetallicRoughness=gl.PbrMetallicRoughness(
                baseColorFactor=[0.27, 0.43, 0.78, 1.0], metallicFactor=0.0, roughnessFactor=0.9
            ),
        )
    ]
    primitive = gl.Primitive(
        attributes=gl.Attributes(POSITION=position, NORMAL=normal),
        indices=indices,
        material=0,
        targets=targets or None,
    )
    names = [f"frame_{f:05d}" for f in keys.frames[1:]]
    meshes = [
        gl.Mesh(
            name=str(anim.attrs.get("garment", "garment")),
            primitives=[primitive],
            weights=[0.0] * len(targets) or None,
            extras={"targetNames": names} if names else None,
        )
    ]
    nodes = [gl.Node(name="garment", mesh=0)]
    samplers, channels = [], []
    if len(targets):
        times = (keys.frames / anim.fps).astype(np.float32)
        weights = np.zeros((len(keys.frames), len(targets)), np.float32)
        weights[np.arange(1, len(keys.frames)), np.arange(len(targets))] = 1.0
        samplers.append(
            gl.AnimationSampler(
                input=blob.stored(times, "SCALAR", bounds=True),
                output=blob.stored(weights.ravel(), "SCALAR"),
                interpolation="LINEAR",
            )
        )
        channels.append(
            gl.AnimationChannel(sampler=0, target=gl.AnimationChannelTarget(node=0, path="weights"))
        )
    scene_nodes, skins = [0], []
    parts = {
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials,
        "samplers": samplers,
        "channels": channels,
        "skins": skins,
    }
    if with_body:
        scene_nodes.append(add_capsule_body(gl, blob, anim, gltf_parts=parts))
    if character is not None:
        times = blob.stored((np.arange(anim.num_frames) / anim.fps).astype(np.float32), "SCALAR", bounds=True)
        scene_nodes.extend(add_character(gl, blob, anim, character=character, gltf_parts=parts, times=times))
    gltf = gl.GLTF2(
        asset=gl.Asset(generator="hrr_garment", version="2.0"),
        scene=0,
        # the clip's rate and length where an importer that reads scene extras (Blender's, into the
        # scene's custom properties) can set its timeline from them: glTF itself has only seconds
        scenes=[
            gl.Scene(
                name=str(anim.attrs.get("source_motion", "animation")),
                nodes=scene_nodes,
                extras={"fps": anim.fps, "frames": anim.num_frames},
            )
        ],
        nodes=nodes,
        meshes=meshes,
        materials=materials,
        skins=skins,
        accessors=blob.accessors,
        bufferViews=blob.views,
        buffers=[gl.Buffer(byteLength=blob.size)],
        animations=[gl.Animation(name="garment", samplers=samplers, channels=channels)] if channels else [],
        extras={
            "fps": anim.fps,
            "keyframe_tolerance_m": tolerance,
            "keyframe_max_error_m": keys.max_error,
            # the cloth animated, where the animation records one (a model across cloths)
            **({"cloth": anim.material.to_dict()} if anim.material is not None else {}),
        },
    )
    gltf.set_binary_blob(blob.bytes())
    data = b"".join(gltf.save_to_bytes())
    atomic_write_bytes(path, data)
    return GlbReport(path, keys, len(data))
