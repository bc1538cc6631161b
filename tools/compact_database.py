"""Maintenance: rewrite a bundle's retrieval database with each frame stored once.

Bundles written before 2026-11-26 store every stride-1 window of the database in full (W = 10 copies
of each frame's latents and standardised motion: 2.5 GB for real-quick); they load and run as they
are, at that cost in memory and load time. This rewrites ``database.safetensors`` in the frame form
hrr-train writes now (hrr_garment.data.windows.WindowFrames), after checking that every window
reads back bit for bit, and updates bundle.json's hashes. Nothing else of the bundle changes.

    python tools/compact_database.py hrr_work/models/dress-real-quick
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from hrr_garment.artifacts.bundle_loader import load_bundle
from hrr_garment.artifacts.bundle_writer import add_bundle_part
from hrr_garment.data.windows import WindowFrames


def compact(folder: Path) -> tuple[int, int]:
    """Rewrite ``folder``'s database in frame form; returns its file size before and after (bytes)."""
    path = folder / "database.safetensors"
    before = path.stat().st_size
    db = load_bundle(folder).database
    if isinstance(db.latents, WindowFrames):
        return before, before
    db.latents = WindowFrames.of_windows(db.latents, db.sequence, db.start)
    if db.motion is not None:
        db.motion = WindowFrames.of_windows(db.motion, db.sequence, db.start)
        if not np.array_equal(db.motion.first, db.latents.first):
            raise ValueError("the latent and motion windows do not share their frames")
    add_bundle_part(folder, path.name, db.arrays(), numpy=True)
    load_bundle(folder)  # the rewritten bundle loads and passes its checks
    return before, path.stat().st_size


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("model", type=Path, nargs="+", help="model bundle directories")
    args = parser.parse_args()
    for folder in args.model:
        try:
            before, after = compact(folder)
        except ValueError as exc:
            sys.exit(f"{folder}: {exc}")
        print(f"{folder}: database {before / 1e6:.0f} MB -> {after / 1e6:.0f} MB")


if __name__ == "__main__":
    main()
