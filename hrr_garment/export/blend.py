"""``.blend`` export: the animation as Blender opens it, written by Blender itself.

The GLB export (:mod:`.glb`) is imported through the add-on (:mod:`.blender_package`: the clip's
rate and range, smooth shading from each frame's geometry, the body) and saved, in a Blender run as
a program (:mod:`hrr_garment.blender`: ``HRR_BLENDER`` or ``blender`` on PATH; the error says so
without one). Blender saves into a temporary folder; the .blend is then copied beside the target and renamed.
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

from ..blender import run_blender_script
from ..data.animation_file import AnimationFile
from ..errors import OutputError
from ..io_utils import atomic_path
from .blender_package import ADDON_SOURCE
from .glb import write_glb

SCRIPT = Path(__file__).with_name("blend_in_blender.py")


def write_blend(
    anim: AnimationFile, path: str | Path, tolerance: float = 0.001, with_body: bool = False
) -> Path:
    """Write ``anim`` as a .blend (``tolerance`` and ``with_body`` as for :func:`.glb.write_glb`)."""
    path = Path(path)
    with tempfile.TemporaryDirectory(prefix="hrr-blend-") as folder:
        glb = write_glb(
            anim, Path(folder) / f"{path.stem}.glb", tolerance=tolerance, with_body=with_body
        ).path
        # Blender saves into the private folder (over an existing file it would leave a .blend1 backup)
        saved = Path(folder) / "saved.blend"
        run_blender_script(
            SCRIPT, [str(ADDON_SOURCE), str(glb), str(saved)], subject=path, what="writing a .blend"
        )
        with atomic_path(path) as tmp:
            try:
                shutil.copyfile(saved, tmp)
            except FileNotFoundError:
                raise OutputError(path, "Blender finished without writing the .blend") from None
    return path
