"""Run the Blender add-on's import (File > Import > hrr_garment animation) on one file, in Blender,
as a user would, and exit as the package's commands do: 0 when it imported, 2 with one ``error:``
line when the add-on refused the file (its report), 1 with the traceback when anything raised.
tools/fuzz_doors.py's "blender add-on" cases run it on damaged exports.

    blender -b --factory-startup -P tools/blender_addon_import.py -- --addon=hrr_garment_blender.zip FILE
    python tools/blender_addon_import.py --addon=hrr_garment_blender.zip FILE   # a Python with bpy
"""

from __future__ import annotations

import os
import sys
import tempfile


def main() -> int:
    args = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else sys.argv[1:]
    addon = [a.split("=", 1)[1] for a in args if a.startswith("--addon=")]
    files = [a for a in args if not a.startswith("--")]
    if len(addon) != 1 or len(files) != 1:
        print("usage: blender_addon_import.py --addon=ADDON.zip FILE", file=sys.stderr)
        return 2
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.extensions.package_install_files(filepath=addon[0], repo="user_default", enable_on_install=True)
    # Blender's own importers log their tracebacks when a file defeats them, even where the add-on
    # catches the failure: held back, and shown only when an exception escaped the add-on
    log, saved = tempfile.TemporaryFile(), os.dup(2)
    sys.stderr.flush()
    os.dup2(log.fileno(), 2)
    try:
        bpy.ops.import_scene.hrr_garment(filepath=files[0])
        outcome = None
    except RuntimeError as exc:  # the operator reported an error, or an exception escaped it
        outcome = str(exc).strip()
    finally:
        sys.stderr.flush()
        os.dup2(saved, 2)
    if outcome is None:
        return 0
    if "Traceback" in outcome:
        log.seek(0)
        print(log.read().decode(errors="replace") + outcome, file=sys.stderr)
        return 1
    print(f"hrr_garment add-on: error: {outcome.removeprefix('Error: ').strip()}", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main())
