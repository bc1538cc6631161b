"""hrr-demo: the current end-to-end job on built-in inputs.

At this stage: synthesize procedural motions, load a real CMU clip, print their summaries and
feature shapes, write a skeleton preview image, then simulate a small dress on a walk and a spin
(newton cloth; the first run on a machine compiles kernels for about a minute) and write the
garment preview. Outputs go to <workspace>/demo; a re-run reuses the finished simulations.
"""

from __future__ import annotations

import argparse
import json
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
    parser.add_argument("--no-sim", action="store_true", help="skip the cloth simulation")
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
    if not args.no_sim:
        _simulate(out)
    return 0


def _simulate(out: Path) -> None:
    """The tiny preset's dress on a 2 s walk and spin, through the real dataset builder."""
    from ..garment.templates import make_garment
    from ..sim.build import build_dataset
    from ..sim.plan import load_preset, plan_sequences
    from ..sim.simulator import SimConfig

    preset = load_preset("tiny")
    garment = make_garment("dress", preset.vertices)
    specs = plan_sequences(preset, ["walk", "spin"], 2.0)
    report = build_dataset(garment, specs, SimConfig.from_dict(preset.sim), out / "dress-demo.h5", splits=preset.splits)
    s = report.summary
    print(f"== cloth: {garment.num_vertices}-vertex dress, {s['sequences']} sequences, {s['frames']} frames -> {report.path}")
    print(f"   strain p99 {s['strain_p99']:.3f}, worst-frame penetration {100 * s['penetration_frame_max']:.2f} %, "
          f"hem swing (m) {json.dumps({k: round(v, 3) for k, v in s['hem_swing_m_by_kind'].items()})}")
    print(f"   garment preview: {report.preview}")


def main(argv: Sequence[str] | None = None) -> int:
    return run_cli(_body, argv, "hrr-demo")


if __name__ == "__main__":
    sys.exit(main())
