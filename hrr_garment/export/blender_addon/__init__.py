"""Blender add-on: File > Import > hrr_garment animation (.glb, .usd, .pc2).

Runs inside Blender (4.2 and later), not in the package: ``hrr-blender-addon -o X.zip`` packs this
folder, and Blender installs the zip (Edit > Preferences > Get Extensions > Install from Disk).

What it does that Blender's own importers leave to the user (measured with tools/blender_check.py):
- the scene's frame rate is the clip's *before* the import, so keys land on whole frames (a GLB
  carries seconds only; the rate comes from the scene extras hrr-export writes);
- the frame range is the clip's, 0 to T - 1 (the importers leave 1-250, which skips frame 0 and
  holds the last pose);
- a GLB is imported with smooth shading computed from each frame's geometry instead of the file's
  normals: Blender reads a GLB's base normals as custom normals and ignores the morph targets',
  which would light every frame with frame 0's normals (22 degrees off at the 99th percentile on a
  CMU walk, up to 155);
- a USD file's rate (Blender's importer sets the range only) from the custom properties
  hrr-export writes on its root;
- a PC2 comes with its base OBJ (same name beside it) and a Mesh Cache modifier at the modifier's
  default axes, the ones that match the OBJ importer's.
"""

from __future__ import annotations

import os

import bpy
from bpy.props import FloatProperty, StringProperty
from bpy_extras.io_utils import ImportHelper

from .files import checked_timeline, glb_timeline, pc2_frames

DEFAULT_FPS = 30.0  # out.h5's rate unless the clip had another: a PC2 does not store it


def _blender_import(path: str, what: str, run) -> None:
    """``run()``, one of Blender's own importers on ``path``; its failure (a RuntimeError that says
    only "Couldn't parse glTF") becomes a ValueError that names the file."""
    try:
        run()
    except RuntimeError as exc:
        lines = str(exc).strip().splitlines()
        reason = lines[-1].removeprefix("Error: ").strip() if lines else ""
        raise ValueError(f"{path}: Blender's {what} importer could not read it ({reason})") from None


def _set_timeline(scene, fps: float, frames: int) -> None:
    scene.render.fps = max(1, round(fps))
    scene.render.fps_base = scene.render.fps / fps  # exact for rates that are not whole numbers
    scene.frame_start, scene.frame_end = 0, frames - 1
    scene.frame_set(0)


class ImportHrrGarment(bpy.types.Operator, ImportHelper):
    """Import a garment animation written by hrr-export (GLB, USD, or PC2 with its OBJ beside it)"""

    bl_idname = "import_scene.hrr_garment"
    bl_label = "Import hrr_garment animation"
    bl_options = {"REGISTER", "UNDO"}

    filename_ext = ".glb"
    filter_glob: StringProperty(default="*.glb;*.pc2;*.usd;*.usdc;*.usda", options={"HIDDEN"})
    fps: FloatProperty(
        name="Frame rate (PC2)",
        default=DEFAULT_FPS,
        min=1.0,
        max=1000.0,
        description="A PC2 file does not store its rate: the clip's (out.h5's fps)",
    )

    def execute(self, context):
        path = self.filepath
        try:
            if path.lower().endswith(".pc2"):
                self._import_pc2(context, path)
            elif path.lower().endswith((".usd", ".usdc", ".usda")):
                self._import_usd(context, path)
            else:
                self._import_glb(context, path)
        except (OSError, ValueError, RuntimeError) as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        return {"FINISHED"}

    def _import_glb(self, context, path: str) -> None:
        timeline = glb_timeline(path)
        if timeline is None:
            self.report(
                {"WARNING"},
                f"{os.path.basename(path)} has no hrr-export timeline: imported at the scene's rate",
            )
        else:
            _set_timeline(context.scene, *timeline)
        _blender_import(
            path, "glTF", lambda: bpy.ops.import_scene.gltf(filepath=path, import_shading="SMOOTH")
        )
        if timeline is not None:
            _set_timeline(context.scene, *timeline)  # the importer may have moved the range

    def _import_usd(self, context, path: str) -> None:
        _blender_import(path, "USD", lambda: bpy.ops.wm.usd_import(filepath=path))
        roots = [o for o in context.selected_objects if "fps" in o.keys() and "frames" in o.keys()]
        if not roots:
            self.report(
                {"WARNING"}, f"{os.path.basename(path)} has no hrr-export timeline: the scene's rate is kept"
            )
            return
        _set_timeline(context.scene, *checked_timeline(path, roots[0]["fps"], roots[0]["frames"]))

    def _import_pc2(self, context, path: str) -> None:
        frames = pc2_frames(path)
        base = os.path.splitext(path)[0] + ".obj"
        if not os.path.isfile(base):
            raise ValueError(
                f"{path}: its base mesh {os.path.basename(base)} is not beside it (hrr-export writes both)"
            )
        _blender_import(base, "OBJ", lambda: bpy.ops.wm.obj_import(filepath=base))
        imported = [o for o in context.selected_objects if o.type == "MESH"]
        if len(imported) != 1:
            raise ValueError(f"{base}: expected one mesh, found {len(imported)}")
        obj = imported[0]
        for polygon in obj.data.polygons:  # OBJs written before smoothing groups import flat
            polygon.use_smooth = True
        cache = obj.modifiers.new("hrr_garment point cache", "MESH_CACHE")
        cache.cache_format, cache.filepath = "PC2", path
        _set_timeline(context.scene, self.fps, frames)


def _menu(self, context):
    self.layout.operator(ImportHrrGarment.bl_idname, text="hrr_garment animation (.glb, .usd, .pc2)")


def register():
    """Blender calls this when the add-on is enabled: the operator and its File > Import entry."""
    bpy.utils.register_class(ImportHrrGarment)
    bpy.types.TOPBAR_MT_file_import.append(_menu)


def unregister():
    """Blender calls this when the add-on is disabled."""
    bpy.types.TOPBAR_MT_file_import.remove(_menu)
    bpy.utils.unregister_class(ImportHrrGarment)
