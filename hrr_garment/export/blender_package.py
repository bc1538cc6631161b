"""The Blender add-on (:mod:`.blender_addon`) as the zip Blender installs.

Blender 4.2 and later install an extension from a zip with ``blender_manifest.toml`` at its root
(Edit > Preferences > Get Extensions > Install from Disk). The add-on's files run inside Blender
only; this module packs them, it does not import them.
"""

from __future__ import annotations

import io
import zipfile
from pathlib import Path

from ..io_utils import atomic_write_bytes

ADDON_SOURCE = Path(__file__).with_name("blender_addon")
ADDON_FILES = ("__init__.py", "files.py", "blender_manifest.toml")


def addon_zip_bytes() -> bytes:
    """The add-on's zip, byte for byte the same on every build (fixed timestamps, fixed order)."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as zf:
        for name in ADDON_FILES:
            info = zipfile.ZipInfo(name, date_time=(2026, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            zf.writestr(info, (ADDON_SOURCE / name).read_bytes())
    return buffer.getvalue()


def write_addon_zip(path: str | Path) -> Path:
    """Write the add-on's zip to ``path``, atomically."""
    path = Path(path)
    atomic_write_bytes(path, addon_zip_bytes())
    return path
