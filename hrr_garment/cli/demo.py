"""hrr-demo: the current end-to-end job on built-in inputs.

Synthesize procedural motions, load a real CMU clip, print their summaries and feature shapes,
write a skeleton preview image; then train the dress model of the ``--preset`` (default quick:
simulation, autoencoder and code space, about 25 minutes on 2 cores the first time; every stage is
reused afterwards) exactly as ``hrr-train --garment dress`` does, and animate the CMU clip (or a
procedural walk without the shared data) into <workspace>/demo/out.h5, and render it to
<workspace>/demo/preview.gif.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Sequence

from ..motion.features import motion_features
from ..motion.io import load_motion
from ..motion.synth import synthesize
from ..motion.windows import windows
from ..paths import find_mocap_dir, workspace
from ._common import run_cli


def _body(argv: Sequence[str] | None) -> int:
    parser = argparse.ArgumentParser(prog="hrr-demo", description=__doc__)
    parser.add_argument("--out", default=None, help="output folder (default: <workspace>/demo)")
    parser.add_argument(
        "--preset", default="quick", help="training preset of the demo model (tiny: a few minutes)"
    )
    parser.add_argument("--no-train", action="store_true", help="stop after the motion part")
    args = parser.parse_args(argv)
    out = workspace() / "demo" if args.out is None else Path(args.out)
    rows = []
    for kind, seed in (("walk", 0), ("spin", 1), ("dance", 2)):
        motion = synthesize(kind, seconds=4.0, seed=seed)
        rows.append((f"procedural {kind} (seed {seed})", motion))
    mocap = find_mocap_dir()
    clip = mocap / "cmu" / "02_01.bvh" if mocap else None
    if clip is not None and clip.exists():
        rows.append((f"CMU {clip.name}", load_motion(clip)))
    else:
        print(
            "CMU sample clips not found (looked for shared/data/mocap; set HRR_MOCAP_DIR); "
            "skipping the real clip"
        )
    for label, motion in rows:
        feats = motion_features(motion)
        s = motion.summary()
        print(f"== {label}")
        print(
            f"   skeleton={s['source_skeleton']} frames={s['frames']} fps={s['fps']:.0f} "
            f"duration={s['duration_s']:.2f}s height={s['height_m']:.2f}m "
            f"root travel={s['root_displacement_m']:.2f}m "
            f"mean lowest foot={100 * s['mean_lowest_foot_height_m']:.1f}cm"
        )
        print(f"   features {feats.shape}, windows {windows(feats).shape}")
    try:
        from ..export.preview import render_skeleton_preview
    except ImportError as exc:  # pragma: no cover - preview extra missing
        print(f"no preview image: {exc}")
        return 0
    path = render_skeleton_preview(rows, out / "skeleton_preview.png")
    print(f"skeleton preview: {path}")
    if args.no_train:
        return 0
    from .animate import main as animate_main
    from .train import main as train_main

    print(f"== training the dress model ({args.preset} preset; reused when already trained)")
    if train_main(["--garment", "dress", "--preset", args.preset]) != 0:
        return 2
    motion_file = clip
    if motion_file is None or not motion_file.exists():
        from ..motion.io import save_motion

        motion_file = out / "walk.npz"
        save_motion(synthesize("walk", seconds=6.0, seed=5), motion_file)
    model = workspace() / "models" / f"dress-{args.preset}"
    _say_dataset(model)
    print(f"== animating {motion_file.name}")
    if animate_main([str(motion_file), "-o", str(out / "out.h5"), "--model", str(model)]) != 0:
        return 2
    from .preview import main as preview_main

    print("== rendering a preview (15 fps GIF, front and left views)")
    return preview_main([str(out / "out.h5"), "-o", str(out / "preview.gif"), "--every", "2", "--color-mode"])


def _say_dataset(model: Path) -> None:
    """Print which dataset the demo model was trained on (its bundle records it)."""
    from ..artifacts.typed_manifest import read_manifest
    from ..data.dataset import GarmentDataset

    dataset = Path(read_manifest(model).dataset or "")
    if not dataset.is_file():
        print(f"   trained on {dataset} (no longer there)")
        return
    ds = GarmentDataset(dataset)
    print(
        f"   trained on {dataset}: preset {ds.info.get('preset', '?')}, {len(ds.names)} sequences, "
        f"{sum(ds.frames.values())} frames"
    )


def main(argv: Sequence[str] | None = None) -> int:
    """``hrr-demo``; returns the exit status."""
    return run_cli(_body, argv, "hrr-demo")


if __name__ == "__main__":
    sys.exit(main())
