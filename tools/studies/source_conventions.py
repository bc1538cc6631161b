"""What differs between two motion sources once the reader has made them canonical (issue 84):
conventions (frame rate and filtering, floor, rest height) or the motion itself.

    python tools/studies/source_conventions.py --source bandai hrr_work/mocap/bandai \\
        --source cmu hrr_work/mocap/cmu-01-09 --every 3 -o hrr_work/eval/source_conventions.json
    python tools/studies/source_conventions.py --source cmu hrr_work/mocap/cmu-01-09 --every 2 \\
        --procedural 3 -o hrr_work/eval/carriage.json

Per source, over its clips as the pipeline reads them (30 fps, retargeted, grounded): the native
frame rate; the joints' acceleration RMS (m/s^2) and the share of their velocity's energy above
6 Hz (high-frequency content: marker noise and filtering, not motion, lives there); the lowest sole
point's height (share of frames within 3 cm of the floor, share more than 10 cm above it); the
pelvis height and the root's horizontal speed; and each motion-feature group's mean magnitude
(what the model reads); how the body is carried (the pelvis's pitch, the chest's lean from it and
its turn's spread, the collars' rotation: :func:`hrr_garment.motion.synth.posture.carriage`). With
``--procedural N``, the procedural library as a source beside them: N seeds of every kind, 4 s each,
their carriage drawn (``--upright``: the kinds' own). For sources recorded faster than 30 fps, the
same read at their own rate and low-pass filtered before keeping every n-th frame (an anti-alias
filter) beside the plain decimation the reader does, so the share that is aliased noise shows.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from tqdm import tqdm

from hrr_garment.motion.bvh import read_bvh
from hrr_garment.motion.features import motion_features
from hrr_garment.motion.io import load_motion
from hrr_garment.motion.synth import KINDS, synthesize
from hrr_garment.motion.synth.posture import carriage

FPS = 30.0
HIGH_HZ = 6.0


def high_frequency_share(positions: np.ndarray, fps: float) -> float:
    """The share of the joints' velocity energy above :data:`HIGH_HZ` (positions (T, J, 3))."""
    velocity = np.diff(positions, axis=0) * fps
    velocity = velocity - velocity.mean(0)
    spectrum = np.abs(np.fft.rfft(velocity, axis=0)) ** 2
    hz = np.fft.rfftfreq(len(velocity), 1.0 / fps)
    total = spectrum.sum()
    return float(spectrum[hz > HIGH_HZ].sum() / total) if total > 0 else 0.0


def acceleration_rms(positions: np.ndarray, fps: float) -> float:
    accel = (positions[2:] - 2 * positions[1:-1] + positions[:-2]) * fps**2
    return float(np.sqrt((accel**2).sum(-1).mean()))


def anti_aliased(path: Path, native: float) -> np.ndarray:
    """Joint positions read at the native rate, box-filtered over one output frame, every n-th kept."""
    step = int(round(native / FPS))
    positions = load_motion(path, fps=native).joint_positions
    kernel = np.ones(step) / step
    smooth = np.apply_along_axis(lambda x: np.convolve(x, kernel, mode="same"), 0, positions)
    return smooth[step : len(smooth) - step : step]


def clip_stats(path: Path) -> dict:
    native = 1.0 / read_bvh(path).frame_time
    row = motion_stats(load_motion(path), native)
    if native > FPS * 1.5:
        filtered = anti_aliased(path, native)
        row["accel_rms_filtered"] = acceleration_rms(filtered, FPS)
        row["high_share_filtered"] = high_frequency_share(filtered, FPS)
    return row


def motion_stats(motion, native: float) -> dict:
    """A canonical clip's measures (module docstring); ``native``: its source's frame rate."""
    held = carriage(motion)
    positions = motion.joint_positions
    lowest = motion.lowest_foot_height()
    features = motion_features(motion)
    return {
        "native_fps": native,
        "frames": motion.num_frames,
        "accel_rms": acceleration_rms(positions, FPS),
        "high_share": high_frequency_share(positions, FPS),
        "on_floor": float((np.abs(lowest) < 0.03).mean()),
        "off_floor": float((lowest > 0.10).mean()),
        "pelvis_m": float(np.median(positions[:, 0, 1])),
        "speed_mps": float(
            np.linalg.norm(np.diff(motion.root_translation[:, [0, 2]], axis=0), axis=1).mean() * FPS
        ),
        "feature_r": float(np.abs(features[:, :60]).mean()),
        "feature_v": float(np.abs(features[:, 60:120]).mean()),
        "feature_t": float(np.abs(features[:, 120:123]).mean()),
        "feature_w": float(np.abs(features[:, 123]).mean()),
        "pelvis_pitch_deg": held.pelvis_pitch,
        "chest_lean_deg": held.chest_lean,
        "chest_turn_sd_deg": held.chest_turn_sd,
        "collar_deg": held.collar,
        "pelvis_turn_sd_deg": held.pelvis_turn_sd,
    }


def summarise(rows: list[dict]) -> dict:
    keys = sorted({k for r in rows for k in r})
    out = {"clips": len(rows), "frames": int(sum(r["frames"] for r in rows))}
    for k in keys:
        values = np.array([r[k] for r in rows if k in r], float)
        out[k] = {
            "median": float(np.median(values)),
            "p10": float(np.percentile(values, 10)),
            "p90": float(np.percentile(values, 90)),
        }
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--source", nargs=2, action="append", metavar=("NAME", "FOLDER"), default=[])
    p.add_argument("--procedural", type=int, default=0, help="seeds of every procedural kind as a source")
    p.add_argument("--upright", action="store_true", help="the procedural clips without a drawn carriage")
    p.add_argument("--every", type=int, default=1, help="every n-th clip of each source, in name order")
    p.add_argument("-o", "--output", type=Path, required=True)
    args = p.parse_args()
    report = {}
    for name, folder in args.source:
        files = sorted(Path(folder).rglob("*.bvh"))[:: args.every]
        rows = [clip_stats(f) for f in tqdm(files, desc=name)]
        report[name] = summarise(rows)
    if args.procedural:
        posture = "upright" if args.upright else "drawn"
        clips = [synthesize(k, 4.0, seed=s, posture=posture) for k in KINDS for s in range(args.procedural)]
        report["procedural"] = summarise([motion_stats(m, FPS) for m in tqdm(clips, desc="procedural")])
    if not report:
        p.error("give at least one --source or --procedural")
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps(report, indent=2))
    keys = [k for k in next(iter(report.values())) if k not in ("clips", "frames")]
    print("| measure | " + " | ".join(report) + " |")
    print("|---|" + "---:|" * len(report))
    for k in keys:
        cells = [
            f"{r[k]['median']:.3g} ({r[k]['p10']:.3g}-{r[k]['p90']:.3g})" if k in r else "-"
            for r in report.values()
        ]
        print(f"| {k} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
