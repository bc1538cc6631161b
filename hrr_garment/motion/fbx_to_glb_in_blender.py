"""Run by Blender, not imported (hrr_garment.motion.fbx): an FBX file's skeleton and animation
re-written as a GLB, which hrr_garment.motion.gltf reads. Arguments after ``--``: the FBX, the GLB.

Blender's FBX importer turns the file's units and axes into Blender's (metres, Z up) and its
glTF exporter into glTF's (metres, Y up); bones keep their names, so joint maps match by name as
for the FBX itself. Keys are sampled on every frame of the action, in seconds at the rate the FBX
declares.
"""

import sys

import bpy

ERROR = "HRR-ERROR: "  # hrr_garment.blender.ERROR_PREFIX: this runs in Blender's Python, without the package


def main() -> int:
    """Convert; 0, or 1 with an HRR-ERROR line naming what the file lacks."""
    source, target = sys.argv[sys.argv.index("--") + 1 :][:2]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    try:
        bpy.ops.import_scene.fbx(filepath=source)
    except RuntimeError as exc:  # Blender's importer reports a damaged or non-FBX file this way
        print(f"{ERROR}not an FBX file Blender can read: {str(exc).strip().splitlines()[-1][:200]}")
        return 1
    armatures = [o for o in bpy.context.scene.objects if o.type == "ARMATURE"]
    if not armatures:
        print(f"{ERROR}no skeleton (armature) in the FBX file")
        return 1
    animated = [a for a in armatures if a.animation_data and a.animation_data.action]
    if not animated:
        print(f"{ERROR}the FBX file's skeleton has no animation")
        return 1
    if len(animated) > 1:
        print(f"{ERROR}{len(animated)} animated skeletons in the FBX file; export the character's alone")
        return 1
    bpy.ops.export_scene.gltf(
        filepath=target,
        export_format="GLB",
        export_animations=True,
        export_skins=True,
        export_materials="NONE",
        export_force_sampling=True,
        export_anim_single_armature=True,
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
