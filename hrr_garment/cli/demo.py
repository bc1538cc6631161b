"""hrr-demo: the current end-to-end job on built-in inputs.

At this stage: synthesize procedural motions, load a real CMU clip, print their summaries and
feature shapes, and write a skeleton preview image into the workspace.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Sequence

from ..motion.features import motion_features, windows
from ..motion.io import load_motion
from ..motion.synth import synthesize
from ..paths import find_mocap_dir, workspace
from ._common import run_cli


def _body(argv: Sequence[str] | None) -> int:
    parser = argparse.ArgumentParser(prog="hrr-demo", description=__doc__)
    parser.add_argument("--out", default=None, help="output folder (default: <workspace>/demo)")
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
        print("CMU sample clips not found (looked for shared/data/mocap; set HRR_MOCAP_DIR); skipping the real clip")
    for label, motion in rows:
        feats = motion_features(motion)
        s = motion.summary()
        print(f"== {label}")
        print(f"   skeleton={s['source_skeleton']} frames={s['frames']} fps={s['fps']:.0f} duration={s['duration_s']:.2f}s "
              f"height={s['height_m']:.2f}m root travel={s['root_displacement_m']:.2f}m mean lowest foot={100 * s['mean_lowest_foot_height_m']:.1f}cm")
        print(f"   features {feats.shape}, windows {windows(feats).shape}")
    try:
        from ..export.preview import render_skeleton_preview
    except ImportError as exc:  # pragma: no cover - preview extra missing
        print(f"no preview image: {exc}")
        return 0
    path = render_skeleton_preview(rows, out / "skeleton_preview.png")
    print(f"skeleton preview: {path}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    return run_cli(_body, argv, "hrr-demo")


if __name__ == "__main__":
    sys.exit(main())
