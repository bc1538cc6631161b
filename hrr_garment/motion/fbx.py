"""FBX motion, read through Blender: the file's skeleton and animation re-written as a GLB by
Blender's own importer and exporter (``fbx_to_glb_in_blender.py``, run by
:func:`hrr_garment.blender.run_blender_script`), then read as any glTF motion
(:mod:`.gltf`: joints matched by name, retargeted, grounded, resampled).

FBX is Autodesk's format, without an open reader that handles its versions and conventions;
Blender's importer is the open one artists already use. It is a program of its own here (its Python
pins another numpy), so reading FBX needs a Blender installed, found as ``HRR_BLENDER`` or
``blender`` on PATH; without one the error says so.
"""

from __future__ import annotations

import tempfile
import warnings
from pathlib import Path

from ..blender import run_blender_script
from ..errors import InputError, MotionError
from .gltf import GltfSettings, load_gltf
from .motion import Motion

FBX_SUFFIX = ".fbx"
SCRIPT = Path(__file__).with_name("fbx_to_glb_in_blender.py")


def load_fbx(path: str | Path, options: GltfSettings = GltfSettings(), ground: bool = True) -> Motion:
    """An FBX animation as canonical motion (``options`` as for :func:`.gltf.load_gltf`; FBX takes
    beyond the first are not read: ``options.animation`` must be None)."""
    path = Path(path)
    if options.animation is not None:
        raise MotionError(
            path, "an FBX file is read for its current take only; choose a glTF file for named animations"
        )
    with tempfile.TemporaryDirectory(prefix="hrr-fbx-") as folder:
        glb = Path(folder) / f"{path.stem}.glb"
        try:
            run_blender_script(SCRIPT, [str(path.resolve()), str(glb)], subject=path, what="reading FBX")
        except InputError as exc:
            raise MotionError(path, exc.problem) from None
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                motion = load_gltf(glb, options, ground=ground)
            except MotionError as exc:  # name the user's file, not the conversion's
                raise type(exc)(path, exc.problem.replace(str(glb), path.name)) from None
    for w in caught:  # the same warnings, naming the FBX
        warnings.warn(str(w.message).replace(str(glb), str(path)), w.category, stacklevel=2)
    motion.source = str(path)
    return motion
