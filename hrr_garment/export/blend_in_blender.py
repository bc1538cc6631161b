"""Run by Blender, not imported (hrr_garment.export.blend): an export of ours imported through the
add-on (hrr_garment/export/blender_addon), saved as a .blend. Arguments after ``--``: the add-on's
folder, the file to import (GLB), the .blend to write."""

import importlib.util
import sys
from pathlib import Path

import bpy

ERROR = "HRR-ERROR: "  # hrr_garment.blender.ERROR_PREFIX: this runs in Blender's Python, without the package


def main() -> int:
    """Import and save; 0, or 1 with an HRR-ERROR line."""
    addon, source, target = sys.argv[sys.argv.index("--") + 1 :][:3]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    spec = importlib.util.spec_from_file_location(
        "hrr_garment_import", Path(addon) / "__init__.py", submodule_search_locations=[addon]
    )
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    module.register()
    try:  # unregistered before the end: the bpy module (PyPI) hangs on exit with the class registered
        if bpy.ops.import_scene.hrr_garment(filepath=source) != {"FINISHED"}:
            print(f"{ERROR}Blender could not import the animation")
            return 1
        bpy.ops.wm.save_as_mainfile(filepath=target, compress=True, copy=True)
    finally:
        module.unregister()
    return 0


if __name__ == "__main__":
    sys.exit(main())
