"""The exported step's push-out (the torch stage an ONNX graph holds: the visible body's collider
graph within the margin of its hulls, float32) against the package's push-out (the C kernel with its
broad phase and winding test) on the same cloth and body: how many vertices a frame each moves, and
how many end more than 1 mm apart, on how many frames, and how far at worst.

The cloth is a dataset's simulated frames on a character's body (``hrr-simulate --body``), as they
are and pulled 2 cm toward the pelvis's vertical axis (into the legs and hips, as a model's mean
cloth lies), the first ``--frames`` of each sequence.

    python tools/studies/make_characters.py -o hrr_work/characters --styles plain
    hrr-body fit hrr_work/characters/plain.glb -o hrr_work/characters/plain.json
    hrr-simulate --garment dress --preset quick --body hrr_work/characters/plain.json \\
        --motions ../shared/data/mocap/cmu/02_01.bvh ../shared/data/mocap/cmu/131_03.bvh \\
        -o hrr_work/study/dress-plain.h5 --no-preview
    python tools/studies/graph_push_study.py hrr_work/characters/plain.json hrr_work/study/dress-plain.h5
"""

from __future__ import annotations

import argparse

import numpy as np
import torch

PULL_M = 0.02  # the cloth pulled this far toward the pelvis's vertical axis
APART_M = 0.001  # two pushes that end farther apart than this differ
STEP = 16  # frames a stage call: 16 characters of a crowd's step


def pulled_in(frames: np.ndarray, motion) -> np.ndarray:
    """``frames`` (T, V, 3) each vertex moved ``PULL_M`` toward the pelvis's vertical axis."""
    off = frames - motion.joint_positions[:, :1].astype(np.float32)
    off[..., 1] = 0.0
    length = np.maximum(np.linalg.norm(off, axis=-1, keepdims=True), 1e-6)
    return (frames - PULL_M * off / length).astype(np.float32)


def compare(visible, frames: np.ndarray, motion, faces: np.ndarray) -> dict:
    """Both push-outs of ``frames`` (T, V, 3) float32 and how they differ."""
    from hrr_garment.inference.collision import PushOutSettings, mean_operator, push_out
    from hrr_garment.inference.edge_limits import EdgeLimits
    from hrr_garment.inference.torch_push_out import PushOutStage
    from hrr_garment.inference.visible_push import PosedSkin

    settings = PushOutSettings()
    mean = mean_operator(faces, frames.shape[1])
    limits = EdgeLimits.of(faces, frames[0].astype(np.float64), mean)
    package, _ = push_out(
        frames, motion, faces, body=PosedSkin.of(visible, motion), settings=settings, mean=mean,
        limits=limits, report=False,
    )  # fmt: skip
    stage = PushOutStage.of_visible(visible, mean, limits=limits, settings=settings)
    rot = torch.from_numpy(motion.global_rotations).float()
    pos = torch.from_numpy(motion.joint_positions).float()
    with torch.no_grad():
        graph = np.concatenate(
            [
                stage(torch.from_numpy(frames[s : s + STEP]), rot[s : s + STEP], pos[s : s + STEP]).numpy()
                for s in range(0, len(frames), STEP)
            ]
        )
    apart = np.linalg.norm(graph - package, axis=-1)

    def moved(out):
        return float((np.linalg.norm(out - frames, axis=-1) > 1e-4).sum(1).mean())

    return {
        "moved_package": moved(package),
        "moved_graph": moved(graph),
        "apart_a_frame": float((apart > APART_M).sum(1).mean()),
        "frames_apart_pct": float((apart > APART_M).any(1).mean() * 100),
        "worst_mm": float(apart.max() * 1000),
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("body", help="the character's body.json (hrr-body fit)")
    p.add_argument("dataset", help="a dataset simulated on that body")
    p.add_argument("--frames", type=int, default=120, help="the first frames of each sequence")
    args = p.parse_args()

    from hrr_garment.body.body_file import read_body
    from hrr_garment.body.skinned_body import visible_body
    from hrr_garment.data.dataset import GarmentDataset
    from hrr_garment.inference.visible_push import visible_collider

    record = read_body(args.body)
    visible = visible_collider(record.body, visible_body(record))
    data = GarmentDataset(args.dataset)
    print(
        "sequence | cloth | frames | moved a frame, package / graph | vertices > 1 mm apart a frame "
        "| frames with any | worst mm"
    )
    for name in data.names:
        sequence = data.sequence(name)
        count = min(args.frames, len(sequence.garment))
        motion = sequence.motion.slice(0, count)
        simulated = sequence.garment[:count].astype(np.float32)
        for cloth, frames in (("simulated", simulated), ("pulled 2 cm in", pulled_in(simulated, motion))):
            r = compare(visible, frames, motion, data.template.faces)
            print(
                f"{name} | {cloth} | {count} | {r['moved_package']:.1f} / {r['moved_graph']:.1f} | "
                f"{r['apart_a_frame']:.2f} | {r['frames_apart_pct']:.0f} % | {r['worst_mm']:.2f}"
            )


if __name__ == "__main__":
    main()
