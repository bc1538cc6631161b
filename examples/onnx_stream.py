"""Stream a clip through an exported garment model with onnxruntime alone: what an engine does each
frame, in Python for reading. Needs only numpy and onnxruntime (not hrr_garment).

    hrr-export-model --model hrr_work/models/dress-real-quick --onnx -o dress.onnx
    hrr-motion poses ../shared/data/mocap/cmu/02_01.bvh -o walk.poses.npz
    python examples/onnx_stream.py dress.onnx walk.poses.npz -o walk.garment.npy --characters 4

The graph takes one frame of N characters, their local joint rotations (quaternions x y z w, on
the joints its tensors file lists, in order) and pelvis positions (metres, Y up), and the state it
returned last frame; it returns the garments' world vertices and the next state. A character's
first frame goes in with the state all zeros (``started`` 0). A graph of the sample mode
(``hrr-export-model --mode sample``) also takes ``noise``, two N(0, 1) vectors per character each
frame (the second is read at a character's first frame only): any generator's; here numpy's, seeded
per character, so the same seed draws the same cloth. Here N characters play the same clip,
each from its own start frame, side by side; the first one's garment frames are saved as
(T, V, 3) float32 with the faces in the tensors file beside the graph.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import onnxruntime


def _args() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("graph", type=Path, help="the .onnx file written by hrr-export-model --onnx")
    p.add_argument(
        "poses", type=Path, help="npz of rotations (T, 22, 4) and root (T, 3), as hrr-motion poses writes"
    )
    p.add_argument(
        "-o", "--output", type=Path, default=None, help="save the first character's garment as (T, V, 3) .npy"
    )
    p.add_argument("--characters", type=int, default=1, help="characters stepped together (default 1)")
    p.add_argument("--spacing", type=float, default=1.5, help="metres between the characters (default 1.5)")
    p.add_argument(
        "--seed",
        type=int,
        default=0,
        help="a sample mode's graph: character i draws from seed + i (default 0)",
    )
    return p.parse_args()


def main() -> int:
    """Stream the clip; returns the exit status."""
    args = _args()
    if args.characters < 1:
        sys.exit("--characters must be at least 1")
    session = onnxruntime.InferenceSession(str(args.graph), providers=["CPUExecutionProvider"])
    meta = session.get_modelmeta().custom_metadata_map
    shapes = json.loads(meta["state"])  # each state input's shape per character
    joints = np.load(args.graph.with_name(f"{args.graph.stem}.tensors.npz"))["joint_names"]
    with np.load(args.poses, allow_pickle=False) as poses:
        rotations, roots = poses["rotations"].astype(np.float32), poses["root"].astype(np.float32)
        if "joint_names" in poses.files and list(poses["joint_names"]) != list(joints):
            sys.exit(f"{args.poses}: its joints are not the graph's {list(joints)}")
    frames, n = len(rotations), args.characters
    starts = (np.arange(n) * frames) // n  # each character from its own frame of the clip
    offset = np.zeros((n, 3), np.float32)
    offset[:, 0] = (np.arange(n) - (n - 1) / 2) * args.spacing

    state = {name: np.zeros((n, *shape), np.float32) for name, shape in shapes.items()}
    noise = json.loads(meta["noise"]) if "noise" in meta else None  # per character, a sample mode's graph
    cloth = None  # a model across cloths' graph: each character's cloth, here the one it was exported with
    if "material" in meta:
        values = json.loads(meta["material_default"])  # log10 of each value but the damping (docs/export.md)
        row = [np.log10(values[k]) if k != "damping" else values[k] for k in json.loads(meta["material"])]
        cloth = np.tile(np.float32(row), (n, 1))
    generators = [np.random.default_rng(args.seed + i) for i in range(n)]
    outputs = [o.name for o in session.get_outputs()]
    garment, seconds = [], []
    for t in range(frames):
        rows = (starts + t) % frames
        feed = {"rotations": rotations[rows], "root": roots[rows] + offset, **state}
        if cloth is not None:
            feed["material"] = cloth
        if noise is not None:
            feed["noise"] = np.stack([g.standard_normal(noise, np.float32) for g in generators])
        t0 = time.perf_counter()
        result = dict(zip(outputs, session.run(outputs, feed)))
        seconds.append(time.perf_counter() - t0)
        state = {name: result[f"next_{name}"] for name in shapes}
        garment.append(result["vertices"][0] - offset[0])
    garment = np.stack(garment)
    ms = 1000 * np.array(seconds[10:] or seconds)  # the first frames warm onnxruntime up
    print(
        f"{frames} frames of {n} character(s), {garment.shape[1]} vertices each: step median "
        f"{np.median(ms):.2f} ms, p99 {np.percentile(ms, 99):.2f} ms ({meta.get('garment', '?')} model, body "
        f"{meta.get('body', '?')})"
    )
    if args.output is not None:
        partial = args.output.with_name(f".{args.output.name}.partial")
        with open(partial, "wb") as fh:  # written whole, then renamed: never a half-written file
            np.save(fh, garment)
        partial.replace(args.output)
        print(f"wrote {args.output} {garment.shape}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
