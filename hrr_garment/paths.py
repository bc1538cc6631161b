"""Where generated data lives: the workspace (``$HRR_HOME`` or ``./hrr_work``), and sample mocap."""

from __future__ import annotations

import os
from pathlib import Path


def workspace() -> Path:
    """The git-ignored workspace for datasets, models and caches."""
    return Path(os.environ.get("HRR_HOME", "hrr_work")).resolve()


def find_mocap_dir() -> Path | None:
    """The shared CMU sample clips: ``$HRR_MOCAP_DIR``, else ``shared/data/mocap`` beside a parent folder."""
    env = os.environ.get("HRR_MOCAP_DIR")
    if env:
        return Path(env) if Path(env).is_dir() else None
    for base in (Path.cwd(), *Path.cwd().parents, Path(__file__).resolve().parent.parent):
        for candidate in (base / "shared" / "data" / "mocap", base.parent / "shared" / "data" / "mocap"):
            if candidate.is_dir():
                return candidate
    return None
