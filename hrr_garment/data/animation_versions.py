"""The out.h5 format's versions (``format_version``): which this hrr_garment reads, and the upgrade
of older files to the current one as :func:`~.animation_file.read_animation_h5` reads them.

1 had no body capsules (still read; only what needs the body refuses such a file); 2 added them;
3 renamed ``diagnostics/mode`` to ``diagnostics/retrieved`` (the inference mode is the ``mode``
attribute) and ``diagnostics/source`` to ``diagnostics/match``, and ``retrieved`` no longer marks
the residual and detail modes' frames, whose windows are the regression's with a match's detail;
4 added the skeleton's motion (``body/rotations``, ``body/root_translation``, ``body/offsets``: what
a character's skinned mesh is posed by in an export; older files export without it); 5 renamed the
attribute ``body`` (the name of the body animated on) ``body_name``, beside ``body_record`` and the
``body/`` group, which hold the body itself.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputError

FORMAT_VERSION = 5

#: version 1 and 2 names of the datasets version 3 renamed
OLD_NAMES = {"diagnostics/retrieved": "diagnostics/mode", "diagnostics/match": "diagnostics/source"}
#: versions 1-4 names of the attributes version 5 renamed
OLD_ATTRS = {"body_name": "body"}


def file_version(path: Path, attrs: dict) -> int:
    """The file's format version (1 where it has none): one this hrr_garment reads."""
    version = attrs.get("format_version", 1)
    if isinstance(version, (bool, np.bool_)) or not isinstance(version, (int, np.integer)) or version < 1:
        raise InputError(path, f"format_version must be a positive integer, got {version!r}")
    if version > FORMAT_VERSION:
        raise InputError(
            path,
            f"format version {version} is newer than this hrr_garment reads ({FORMAT_VERSION}); "
            "upgrade hrr_garment",
        )
    return int(version)


def upgrade_from_version_2(per_frame: dict, attrs: dict) -> tuple[dict, dict]:
    """Versions 1-2 -> 3: ``retrieved`` marked every frame of the residual and detail modes (their
    database match), which version 3 records in ``match`` only."""
    if str(attrs.get("mode", "")) in ("residual", "detail"):
        per_frame = {**per_frame, "diagnostics/retrieved": np.zeros_like(per_frame["diagnostics/retrieved"])}
    return per_frame, {**attrs, "format_version": FORMAT_VERSION}


def upgrade_from_version_4(attrs: dict) -> dict:
    """Versions 1-4 -> 5: the attributes under their version 5 names (:data:`OLD_ATTRS`); the
    arrays are as before, so ``format_version`` stays the file's."""
    renamed = {new: attrs[old] for new, old in OLD_ATTRS.items() if old in attrs}
    return {**{k: v for k, v in attrs.items() if k not in OLD_ATTRS.values()}, **renamed}
