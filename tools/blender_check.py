"""Client check: open our exports in Blender and compare what Blender plays with the animation.

Runs inside Blender's Python, not the package's (bpy pins its own numpy), with only bpy and numpy:

    blender -b --factory-startup -P tools/blender_check.py -- \\
        ref.npz dance.glb dance.usdc dance.pc2 dance.blend
    python-with-bpy tools/blender_check.py ref.npz dance.glb --json      # the bpy module from PyPI
    ... --set-fps --gltf-shading=SMOOTH       # as docs/export.md tells a user of the stock importers
    ... --addon=hrr_garment_blender.zip       # through our add-on (hrr-blender-addon)

``ref.npz`` holds the animation as hrr-export read it (``vertices`` (T, V, 3), ``faces`` (F, 3),
``fps``); ``tests/export/test_blender_client.py`` writes it and runs this script when a Blender is
found. Each file is imported into an empty scene as a user would (``.glb`` through the glTF
importer, ``.usd*`` through the USD importer, ``.pc2`` as its base ``.obj`` with a Mesh Cache
modifier set as docs/export.md says, a ``.blend`` opened) and, for every frame of the clip, the evaluated
garment (modifiers, shape keys, animation) is compared with the reference:

- positions: the largest distance of a vertex from its reference position (vertices are matched
  in the file's order, which every importer here keeps);
- normals: the angle between the normal Blender shades each face corner with and the area-weighted
  normal of the reference frame at that vertex (99th percentile and largest, over corners and frames);
- time: the scene's frame rate against the clip's, and its frame range against the frames where
  the clip's first and last frames landed (geometry is compared from where frame 0 landed);
- shading: whether every face is smooth-shaded.

Prints one line per file, or a JSON object per file with ``--json``; exits 1 when a file could
not be imported.
"""

from __future__ import annotations

import json
import sys
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class ImportWay:
    """How the files are imported: as a user of the stock importers would, told to set the scene's
    rate first (``set_fps``) and with the glTF dialog's settings (``gltf``; its defaults unless
    given), or through our add-on (``addon``: installed from its zip first)."""

    addon: bool = False
    set_fps: bool = False
    gltf: dict = field(default_factory=dict)


def _arguments() -> list[str]:
    argv = sys.argv
    return argv[argv.index("--") + 1 :] if "--" in argv else argv[1:]


def vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(V, 3) unit vertex normals of one frame, each face's normal weighted by its corner angle at
    the vertex: what Blender (and most modelling tools) shade with. Area weighting, which three.js
    uses, differs from it by 22 degrees at the 99th percentile on a folded dress."""
    out = np.zeros_like(vertices)
    for k in range(3):
        a, b, c = (vertices[faces[:, (k + j) % 3]] for j in range(3))
        e1, e2 = b - a, c - a
        face = np.cross(e1, e2)
        face /= np.maximum(np.linalg.norm(face, axis=1, keepdims=True), 1e-30)
        cos = (e1 * e2).sum(1) / np.maximum(np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1), 1e-30)
        np.add.at(out, faces[:, k], face * np.arccos(np.clip(cos, -1.0, 1.0))[:, None])
    return out / np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-30)


def _empty_scene(bpy, fps: float | None) -> None:
    """A new empty scene (the preferences, and an installed add-on, stay); at ``fps`` when given
    (the step docs/export.md asks before a glTF import)."""
    bpy.ops.wm.read_homefile(use_empty=True)
    if fps is not None:
        bpy.context.scene.render.fps, bpy.context.scene.render.fps_base = round(fps), 1.0


def _import(bpy, path: str, way: ImportWay) -> list:
    """Import ``path`` as a user would; returns the mesh objects it brought in."""
    lower = path.lower()
    if lower.endswith(".blend"):  # a scene already made (hrr-export --to blend): opened as it is
        bpy.ops.wm.open_mainfile(filepath=path)
    elif way.addon:
        if bpy.ops.import_scene.hrr_garment(filepath=path) != {"FINISHED"}:
            raise ValueError(f"{path}: the add-on's import did not finish")
    elif lower.endswith(".glb") or lower.endswith(".gltf"):
        bpy.ops.import_scene.gltf(filepath=path, **way.gltf)
    elif lower.endswith((".usd", ".usdc", ".usda")):
        bpy.ops.wm.usd_import(filepath=path)
    elif lower.endswith(".pc2"):
        base = path[:-4] + ".obj"
        # docs/export.md: File > Import > Wavefront (defaults), then a Mesh Cache modifier (PC2) at its
        # default axes (the OBJ importer has turned Y up into Z up; the cache applies in the object's frame)
        bpy.ops.wm.obj_import(filepath=base)
        obj = next(o for o in bpy.context.scene.objects if o.type == "MESH")
        cache = obj.modifiers.new("cache", "MESH_CACHE")
        cache.cache_format = "PC2"
        cache.filepath = path
    else:
        raise ValueError(f"{path}: no importer for this extension")
    return [o for o in bpy.context.scene.objects if o.type == "MESH"]


def _evaluated(bpy, obj) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The object as Blender plays it now: world vertices (V, 3) in the file's frame (Y up), the
    shading normal of every face corner (C, 3), each corner's vertex (C,) and each face's smooth flag."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    ev = obj.evaluated_get(depsgraph)
    mesh = ev.to_mesh()
    try:
        n = len(mesh.vertices)
        co = np.empty(3 * n)
        mesh.vertices.foreach_get("co", co)
        world = np.array(ev.matrix_world)
        co = co.reshape(n, 3) @ world[:3, :3].T + world[:3, 3]
        corners = len(mesh.loops)
        normals = np.empty(3 * corners)
        mesh.corner_normals.foreach_get("vector", normals)
        corner_vertex = np.empty(corners, np.int64)
        mesh.loops.foreach_get("vertex_index", corner_vertex)
        normals = normals.reshape(corners, 3) @ world[:3, :3].T
        smooth = np.empty(len(mesh.polygons), bool)
        mesh.polygons.foreach_get("use_smooth", smooth)
    finally:
        ev.to_mesh_clear()
    z_up_to_y_up = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])  # Blender's (x, y, z) -> (x, z, -y)
    normals = normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    return co @ z_up_to_y_up.T, normals @ z_up_to_y_up.T, corner_vertex, smooth


def _error_at(bpy, obj, frame: int, vertices: np.ndarray) -> float:
    bpy.context.scene.frame_set(frame)
    return float(np.linalg.norm(_evaluated(bpy, obj)[0] - vertices, axis=1).max())


def check(bpy, path: str, ref: dict, way: ImportWay = ImportWay()) -> dict:
    """Import ``path`` into an empty scene ``way``'s way and compare every frame with ``ref``."""
    vertices, faces, fps = ref["vertices"].astype(np.float64), ref["faces"], float(ref["fps"])
    _empty_scene(bpy, fps if way.set_fps else None)
    garments = [o for o in _import(bpy, path, way) if len(o.data.vertices) == vertices.shape[1]]
    if len(garments) != 1:
        raise ValueError(
            f"{path}: {len(garments)} imported meshes have the clip's {vertices.shape[1]} vertices"
        )
    obj, scene = garments[0], bpy.context.scene
    frames = len(vertices)
    result = {
        "file": path,
        "scene_fps": scene.render.fps / scene.render.fps_base,
        "clip_fps": fps,
        "frame_start": scene.frame_start,
        "frame_end": scene.frame_end,
        "clip_frames": frames,
    }
    # where the importer put clip frame 0 (scene frame 0 or 1, whatever the scene's range says):
    # geometry is compared there, and the range is judged against it
    first = min({0, 1, scene.frame_start}, key=lambda s: _error_at(bpy, obj, s, vertices[0]))
    result.update(
        clip_frame_0_at=first,
        range_ok=bool(scene.frame_start == first and scene.frame_end == first + frames - 1),
        rate_ok=bool(abs(result["scene_fps"] - fps) < 1e-6),
    )
    scene.frame_set(first)
    smooth = _evaluated(bpy, obj)[3]
    result["smooth_faces"] = float(smooth.mean()) if len(smooth) else 0.0
    worst, angles = 0.0, []
    for f in range(frames):
        scene.frame_set(first + f)
        co, normals, corner_vertex, _ = _evaluated(bpy, obj)
        worst = max(worst, float(np.linalg.norm(co - vertices[f], axis=1).max()))
        expected = vertex_normals(vertices[f], faces)[corner_vertex]
        cos = np.clip((normals * expected).sum(1), -1.0, 1.0)
        angles.append(np.degrees(np.arccos(cos)))
    angles = np.concatenate(angles)
    result.update(
        max_vertex_error_mm=1000 * worst,
        normal_error_p99_deg=float(np.percentile(angles, 99)),
        normal_error_max_deg=float(angles.max()),
    )
    return result


def main() -> int:
    args = _arguments()
    as_json = "--json" in args
    shading = [a.split("=", 1)[1] for a in args if a.startswith("--gltf-shading=")]  # NORMALS, SMOOTH or FLAT
    addon = [a.split("=", 1)[1] for a in args if a.startswith("--addon=")]
    way = ImportWay(
        addon=bool(addon),
        set_fps="--set-fps" in args,
        gltf={"import_shading": shading[-1]} if shading else {},
    )
    args = [a for a in args if not a.startswith("--")]
    if len(args) < 2:
        print(
            __doc__.split("\n\n")[0] + "\nusage: tools/blender_check.py REF.npz FILE [FILE ...] [--json]",
            file=sys.stderr,
        )
        return 2
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    if addon:  # into the user resources Blender was started with (the tests give it a temporary one)
        bpy.ops.extensions.package_install_files(
            filepath=addon[0], repo="user_default", enable_on_install=True
        )
    with np.load(args[0]) as data:
        ref = {k: data[k] for k in ("vertices", "faces", "fps")}
    status = 0
    for path in args[1:]:
        try:
            result = check(bpy, path, ref, way)
        except Exception as exc:  # noqa: BLE001 - one file's failure is reported, the others still run
            result, status = {"file": path, "error": f"{type(exc).__name__}: {exc}"}, 1
        if as_json:
            print(json.dumps(result))
        else:
            print(
                "  ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in result.items())
            )
    return status


if __name__ == "__main__":
    sys.exit(main())
