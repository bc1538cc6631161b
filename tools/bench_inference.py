"""Benchmark: end-to-end inference speed (motion features -> world-space garment vertices).

Builds a model with random weights at the given template resolution and a retrieval database of
realistic size (``--database`` windows; the full preset has about 5,700), or loads a trained one
(``--model``); then times on one procedural clip (or ``--motion FILE``). Speed depends on the
weights only through denormal numbers, which inference flushes to zero; a trained model's
push-out has more work (a dress whose bodice rests on the body) than random weights give it.

- offline animation per mode (hybrid at the default tau, regression-only, retrieval-only), frames/s
  from the clip's features to world vertices, without and with the collision push-out;
- streaming: one ``push`` per frame (features, motion encoder, gate, decoder, push-out), per-frame
  latency percentiles and the median time of each stage, pushed back to back, and paced like a
  game loop (``--pace`` frames/s: the thread idles until the next frame's time, so caches cool and
  idle worker threads must be woken);
- a crowd (``--crowd N ...``): N characters streamed in one call per frame (``animator.crowd()``;
  with ``--device cuda`` the regression as one torch step on the GPU; ``--decoder fast`` the
  subspace decoder, random for random weights),
  each playing the clip from its own start frame and place, poses handed over as an engine does
  (quaternions and roots); p50 / p99 of the whole N-character step, back to back and paced, the
  cost per character and character-frames/s, for each N (the scaling); with ``--crowd-bodies``,
  each crowd also with every character on a body of its own (bones 0.9-1.1 times the mannequin's,
  radii likewise; ``--crowd-bodies anny``: anny bodies sampled as the bodies preset does), the two
  runs alternating ``--crowd-repeat`` times: the step's p99 with N bodies over the p99 with one;
- peak resident memory of the process.

    python tools/bench_inference.py                       # 4,000 and 12,000 vertices
    python tools/bench_inference.py --vertices 4000 --json
    python tools/bench_inference.py --model hrr_work/models/dress-full \\
        --motion ../shared/data/mocap/cmu/131_03.bvh
    python tools/bench_inference.py --vertices 4266 --crowd 1 2 4 8 16 32 64   # the crowd's scaling
    python tools/bench_inference.py --vertices 4000 --crowd 32 --precision bfloat16   # decoder on AMX
    python tools/bench_inference.py --model DIR --crowd 32 --crowd-bodies \\
        --pace 0 --json   # 32 bodies against one
    python tools/bench_inference.py --model DIR --crowd 32 --crowd-bodies anny \\
        --crowd-only --pace 0   # anny's bodies
    python tools/bench_inference.py --vertices 4156 --crowd 1 8 32 64 128 --decoder fast \\
        --crowd-only --pace 0
    python tools/bench_inference.py --vertices 4156 --crowd 1000 --decoder fast --device cuda \\
        --crowd-only --pace 0
"""

from __future__ import annotations

import argparse
import json
import resource
import time
import warnings
from pathlib import Path

import numpy as np
import torch
from machine import cpu_description, gmac_reference_ms

from hrr_garment.artifacts import fold_codec
from hrr_garment.artifacts.bundle import Bundle
from hrr_garment.artifacts.database import CodeDatabase
from hrr_garment.artifacts.folds import FoldStore
from hrr_garment.artifacts.manifest import FORMAT_VERSION
from hrr_garment.artifacts.typed_manifest import Manifest
from hrr_garment.data.windows import WindowFrames
from hrr_garment.garment.templates import make_garment
from hrr_garment.inference.animator import Animator
from hrr_garment.models.codespace import CodeSpace, CodeSpaceSettings
from hrr_garment.models.fcmae import AutoencoderSettings, MeshAutoencoder
from hrr_garment.models.hierarchy import build_hierarchy
from hrr_garment.models.subspace import SubspaceDecoder
from hrr_garment.motion.features import FeatureStats
from hrr_garment.motion.io import load_motion
from hrr_garment.motion.synth import synthesize
from hrr_garment.native import PRECISIONS


def random_bundle(vertices: int, windows: int, seed: int = 0, components: int = 256) -> Bundle:
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    garment = make_garment("dress", vertices)
    ae = MeshAutoencoder(
        build_hierarchy(garment.faces, garment.num_vertices), AutoencoderSettings(), garment.vertices, 0.02
    ).eval()
    cfg = CodeSpaceSettings()
    cs = CodeSpace(cfg, cfg.features, ae.latent_shape).eval()
    size = ae.latent_shape[0] * ae.latent_shape[1]
    sequence, start = np.arange(windows) // 111, np.arange(windows) % 111
    lengths = np.full(
        int(sequence[-1]) + 1, 111 + cfg.window - 1
    )  # every sequence's frames, as many as its windows cover
    frames = int(lengths.sum())

    def random_frames(*shape: int) -> WindowFrames:
        return WindowFrames.of_sequences(
            [rng.normal(size=(n, *shape)).astype(np.float32) for n in lengths], sequence, start, cfg.window
        )

    db = CodeDatabase(
        rng.integers(0, cfg.classes, (windows, cfg.groups)),
        random_frames(*ae.latent_shape),
        sequence,
        start,
        [f"s{i}" for i in range(len(lengths))],
        cfg.classes,
        random_frames(cfg.features),
    )
    manifest = Manifest.parse(  # what the animator reads of bundle.json: no file behind it
        {
            "format_version": FORMAT_VERSION,
            "garment": "dress",
            "autoencoder": {"config": ae.config.to_dict(), "scale": 0.02, "sizes": list(ae.hierarchy.sizes)},
            "codespace": {
                "config": cfg.to_dict(),
                "features": cfg.features,
                "latent_shape": list(ae.latent_shape),
            },
            "tau": 1.0,
            "gate": "entropy",
            "gates": {},
            "database": {"names": db.names, "classes": cfg.classes},
            "files": {},
            "content_hash": "random",
            "validation": "clips",
        },
        "bundle.json",
    )
    blocks = fold_codec.blocks_of(3 * garment.num_vertices)  # as new bundles store them: nf4
    folds = FoldStore(
        rng.integers(0, 256, (frames, blocks, fold_codec.BLOCK // 2), dtype=np.uint8),
        np.full((frames, blocks), 1e-3, np.float16),
        np.r_[0, np.cumsum(lengths)],
        encoding="nf4",
        vertices=garment.num_vertices,
    )
    subspace = SubspaceDecoder(
        ae.latent_shape, garment.num_vertices, components
    )  # random weights: a timing stand-in
    subspace.basis.copy_(torch.linalg.qr(torch.randn(3 * garment.num_vertices, components))[0].T)
    subspace.mean.copy_(torch.from_numpy(garment.vertices.astype(np.float32).ravel()))
    subspace.coeff_std.fill_(1e-3)
    return Bundle(
        Path("."),
        manifest,
        ae,
        cs,
        FeatureStats(np.zeros(cfg.features, np.float32), np.ones(cfg.features, np.float32)),
        FeatureStats(np.zeros(size, np.float32), np.ones(size, np.float32)),
        db,
        garment,
        folds=folds,
        subspace=subspace.eval(),
    )


def _fps(animator: Animator, motion, repeat: int = 3, **kwargs) -> float:
    """Frames/s of offline animation: the median of ``repeat`` timed passes (one pass swung by
    +-15 % from run to run on a 2-core machine)."""
    animator.animate(motion.slice(0, 40), **kwargs)  # warm-up
    seconds = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        animator.animate(motion, **kwargs)
        seconds.append(time.perf_counter() - t0)
    return motion.num_frames / float(np.median(seconds))


def _median_entropy_tau(bundle: Bundle, motion) -> float:
    """A tau at the median window entropy: about half the windows retrieve."""
    from hrr_garment.models.codes import encode_motion
    from hrr_garment.motion.features import motion_features
    from hrr_garment.motion.memory import with_memory
    from hrr_garment.motion.windows import windows as feature_windows

    feats = with_memory(motion_features(motion), motion.fps, bundle.codespace.config.memory)
    windows = np.ascontiguousarray(feature_windows(feats, bundle.codespace.config.window))
    entropy = encode_motion(
        bundle.codespace, bundle.motion_stats, bundle.latent_stats, windows, regression=False
    ).entropy
    return float(np.quantile(entropy, 0.5, method="lower"))


def crowd_bodies(count: int, source: str = "scaled") -> list:
    """``count`` bodies, each its own. ``source`` "scaled": the mannequin's skeleton and capsules
    scaled by 0.9 to 1.1 (no extra needed); "anny": parametric bodies as the bodies preset samples
    them (statures 1.50-1.95 m, genders alternating, weight and muscle slim to heavy; another seed
    than the preset's, so none is a training body; the bodies extra and its cached assets)."""
    if source == "anny":
        from tqdm import tqdm

        from hrr_garment.body.body_file import record_of
        from hrr_garment.body.parametric import parametric_body
        from hrr_garment.sim.body_plan import BodyPlan, sampled_shapes

        shapes = sampled_shapes(BodyPlan("sample", count=count, seed=7))
        return [record_of(parametric_body(shape)) for shape in tqdm(shapes, desc="bodies", disable=None)]
    from hrr_garment.body.body_file import BodyRecord
    from hrr_garment.body.fit import scaled_capsules
    from hrr_garment.motion.skeleton import REST_OFFSETS, REST_PELVIS_HEIGHT, Skeleton

    out = []
    for k in np.linspace(0.9, 1.1, count):
        skeleton = Skeleton(offsets=(REST_OFFSETS * k).astype(np.float32))
        body = scaled_capsules(
            skeleton, skeleton.rest_positions(np.array([0.0, REST_PELVIS_HEIGHT * k, 0.0]))
        )
        out.append(BodyRecord(skeleton, body, pelvis_height=REST_PELVIS_HEIGHT * k, stature=1.7 * k))
    return out


def _ping_pong(frame: np.ndarray, frames: int) -> np.ndarray:
    """Frame indices of a clip of ``frames`` frames played forward, then backward, and so on."""
    period = max(2 * frames - 2, 1)
    phase = frame % period
    return np.where(phase < frames, phase, period - phase)


def bench_crowd(
    animator: Animator,
    motion,
    tau: float,
    characters: int,
    pace: float,
    frames: int = 300,
    bodies: list | None = None,
    decoder: str = "full",
    device: str = "native",
    push: str = "mesh",
    mode: str = "hybrid",
    changes: dict | None = None,
) -> dict:
    """``characters`` streamed together for ``frames`` frames: character i plays ``motion`` from frame
    7 i, forward then backward at its ends (a wrap would jump the pelvis back, which the stream takes
    as a teleport and restarts the character), and stands 2 i metres to the side (on ``bodies[i]``
    where given); returns the step's latency percentiles (ms), back to back and paced at ``pace`` frames/s,
    and the cost per character. ``device``: "native" (the hybrid on the CPU kernels) or a torch device (the
    regression as one torch step there, its output left on the device, the step synchronised);
    ``push``: the push-out's "mesh" or "subspace" push; ``mode``: the native crowd's mode (the hybrid at
    ``tau``, or another that takes no tau: regression, sample), ``changes`` its other run settings."""
    from hrr_garment.motion.rotations import matrix_to_quat

    quats = matrix_to_quat(motion.local_rotations.astype(np.float64))[..., [1, 2, 3, 0]].astype(
        np.float32
    )  # (x, y, z, w)
    offsets = np.arange(characters) * 7
    side = np.stack([2.0 * np.arange(characters), np.zeros(characters), np.zeros(characters)], 1)
    native = device == "native"
    sync = torch.cuda.synchronize if device.startswith("cuda") else (lambda: None)
    out = {}
    for key, fps in (("", 0.0), ("paced_", pace)) if pace else (("", 0.0),):
        crowd = (
            animator.crowd(
                mode=mode,
                **({"tau": tau} if mode == "hybrid" else {}),
                **(changes or {}),
                decoder=decoder,
                device="native",
                push=push,
            )
            if native
            else animator.crowd(mode="regression", decoder=decoder, device=device, push=push)
        )
        with warnings.catch_warnings():  # bodies outside a model's range: timed all the same
            warnings.simplefilter("ignore")
            for i, body in enumerate(bodies or []):
                crowd.set_body(i, body, allow_outside=True)
        start, lat = time.perf_counter(), []
        for t in range(frames):
            if fps:
                time.sleep(max(0.0, start + t / fps - time.perf_counter()))
            idx = _ping_pong(t + offsets, motion.num_frames)
            t0 = time.perf_counter()
            if native:
                crowd.push(quats[idx], motion.root_translation[idx] + side)
            else:
                crowd.push(
                    quats[idx], (motion.root_translation[idx] + side).astype(np.float32), as_tensor=True
                )
                sync()
            lat.append(time.perf_counter() - t0)
        lat = 1000 * np.array(lat)[20:]
        out[f"{key}p50_ms"], out[f"{key}p99_ms"] = (round(float(np.percentile(lat, q)), 2) for q in (50, 99))
        if not key and native:  # where the step's time goes: each stage's median
            out["stage_p50_ms"] = {
                k: round(1000 * float(np.median(np.array(v)[20:])), 3)
                for k, v in crowd.timings.stage_s.items()
            }
    out.setdefault("paced_p50_ms", None), out.setdefault("paced_p99_ms", None)
    out["per_character_us"] = round(1000 * out["p50_ms"] / characters, 1)
    out["character_frames_per_s"] = round(1000 * characters / out["p50_ms"], 1)
    return out


def bench_crowd_bodies(
    animator: Animator,
    motion,
    tau: float,
    characters: int,
    frames: int,
    repeat: int,
    decoder: str = "full",
    source: str = "scaled",
) -> dict:
    """The crowd with one body for all (the model's own) and with a body per character
    (:func:`crowd_bodies` of ``source``), alternating ``repeat`` times, back to back: each run's p50
    and p99, push-out stage median, and the median ratio of the p99s (N bodies over one)."""
    bodies = crowd_bodies(characters, source)
    runs = {"one_body": [], "bodies": []}
    for _ in range(repeat):
        runs["one_body"].append(bench_crowd(animator, motion, tau, characters, 0.0, frames, decoder=decoder))
        runs["bodies"].append(
            bench_crowd(animator, motion, tau, characters, 0.0, frames, bodies=bodies, decoder=decoder)
        )
    ratios = [b["p99_ms"] / o["p99_ms"] for o, b in zip(runs["one_body"], runs["bodies"])]
    return {
        k: [
            {"p50_ms": r["p50_ms"], "p99_ms": r["p99_ms"], "push_out_p50_ms": r["stage_p50_ms"]["push_out"]}
            for r in v
        ]
        for k, v in runs.items()
    } | {
        "bodies_from": source,
        "p99_ratio_median": round(float(np.median(ratios)), 3),
        "p99_ratios": [round(r, 3) for r in ratios],
    }


def _offline_and_stream(
    animator: Animator, motion, tau: float, repeat: int, pace: float, decoder: str
) -> dict:
    """Offline frames/s per mode (push-out off, and the hybrid's with it), and one character streamed
    back to back, without the push-out and paced: latency percentiles and each stage's median."""
    out = {}
    for mode in ("hybrid", "regression", "retrieval", "detail"):
        out[f"fps_{mode}"] = round(
            _fps(animator, motion, repeat, mode=mode, tau=tau, push_out=False, decoder=decoder), 1
        )
    out["fps_hybrid_with_collision"] = round(
        _fps(animator, motion, repeat, mode="hybrid", tau=tau, push_out=True, decoder=decoder), 1
    )
    runs = [("stream", True, 0.0), ("stream_no_collision", False, 0.0)] + (
        [("stream_paced", True, pace)] if pace else []
    )
    for key, collision, fps in runs:
        stream = animator.stream(mode="hybrid", tau=tau, push_out=collision, decoder=decoder)
        start = time.perf_counter()
        for t in range(motion.num_frames):
            if fps:  # a game loop: the next pose arrives at the next frame time, the thread idles until then
                time.sleep(max(0.0, start + t / fps - time.perf_counter()))
            stream.push(motion.slice(t, t + 1))
        lat = 1000 * np.array(stream.latency_s)[20:]  # after warm-up
        out[f"{key}_p50_ms"] = round(float(np.percentile(lat, 50)), 2)
        out[f"{key}_p99_ms"] = round(float(np.percentile(lat, 99)), 2)
        if key == "stream":  # where a streamed frame's time goes
            out["stream_stage_p50_ms"] = {
                k: round(1000 * float(np.median(np.array(v)[20:])), 2) for k, v in stream.stage_s.items()
            }
    return out


def bench(
    vertices: int,
    windows: int,
    seconds: float,
    model: str | None = None,
    motion_file: str | None = None,
    pace: float = 30.0,
    crowd: list[int] | None = None,
    repeat: int = 3,
    precision: str = "float32",
    crowd_frames: int = 300,
    crowd_bodies_repeat: int = 0,
    decoder: str = "full",
    offline: bool = True,
    device: str = "native",
    push: str = "mesh",
    crowd_bodies_from: str = "scaled",
) -> dict:
    """``model``: a trained bundle instead of random weights (its own resolution, database and tau);
    ``motion_file``: a clip instead of the procedural curved walk; ``pace``: frames/s of the paced
    stream run (0: none); ``repeat``: timed passes per offline figure (their median); ``precision``:
    the mesh decoder's arithmetic for batches; ``crowd_frames``: steps per crowd run (the first 20
    are warm-up); ``decoder``: the full mesh decoder or the fast subspace one (streams and crowds);
    ``offline``: also the offline and single-stream figures; ``device``: where the crowds run
    ("native": the CPU kernels; a torch device: the regression as one torch step, e.g. cuda);
    ``push``: the crowds' push-out, "mesh" or "subspace" (the push in the fast decoder's subspace first);
    ``crowd_bodies_from``: the bodies of the crowds on a body each (:func:`crowd_bodies`)."""
    animator = (
        Animator.load(model, precision=precision)
        if model
        else Animator(random_bundle(vertices, windows), precision=precision)
    )
    bundle = animator.bundle
    motion = load_motion(motion_file) if motion_file else synthesize("walk_curve", seconds, seed=0)
    tau = bundle.tau if model else _median_entropy_tau(bundle, motion)
    out = {
        "cpu": cpu_description(),
        "vertices": bundle.template.num_vertices,
        "database_windows": len(bundle.database),
        "clip_frames": motion.num_frames,
        "threads": torch.get_num_threads(),
        "precision": precision,
        "model": model or "random weights",
        "motion": motion_file or "procedural walk_curve",
        "decoder": decoder,
        "crowd_device": device,
        "crowd_push": push,
    }
    if offline:
        out.update(_offline_and_stream(animator, motion, tau, repeat, pace, decoder))
    if crowd:
        # the budget's reference, timed before and after every crowd of this run (tools/machine.py):
        # a step's multiple of it compares across machines
        references = [gmac_reference_ms()]
        out["crowd"] = {}
        for n in crowd:
            out["crowd"][str(n)] = bench_crowd(
                animator, motion, tau, n, pace, crowd_frames, decoder=decoder, device=device, push=push
            )
            references.append(gmac_reference_ms())
        out["reference_ms"] = round(float(np.median(references)), 3)
        out["reference_spread_ms"] = [round(min(references), 3), round(max(references), 3)]
        for c in out["crowd"].values():
            c["p50_x"], c["p99_x"] = (round(c[k] / out["reference_ms"], 3) for k in ("p50_ms", "p99_ms"))
        if crowd_bodies_repeat:
            out["crowd_bodies"] = {
                str(n): bench_crowd_bodies(
                    animator,
                    motion,
                    tau,
                    n,
                    crowd_frames,
                    crowd_bodies_repeat,
                    decoder=decoder,
                    source=crowd_bodies_from,
                )
                for n in crowd
            }
    out["peak_rss_mb"] = round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)
    out["native_decoder"] = animator.decoder.native  # the full decoder's kernels
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--vertices", type=int, nargs="+", default=[4000, 12000])
    parser.add_argument(
        "--database", type=int, default=5700, help="database windows (the full preset has ~5,700)"
    )
    parser.add_argument("--seconds", type=float, default=20.0, help="clip length")
    parser.add_argument(
        "--model", default=None, help="a trained model (directory or garment name) instead of random weights"
    )
    parser.add_argument(
        "--motion", default=None, help="a motion file (BVH / npz) instead of the procedural clip"
    )
    parser.add_argument(
        "--pace",
        type=float,
        default=30.0,
        help="also stream paced at this many frames/s, idle between pushes as in a game (0: skip)",
    )
    parser.add_argument(
        "--crowd",
        type=int,
        nargs="*",
        default=[],
        help="also stream crowds of these many characters, one call per frame (e.g. 1 8 32)",
    )
    parser.add_argument(
        "--crowd-frames",
        type=int,
        default=300,
        help="steps per crowd run, the first 20 warm-up (p99 of 280: the third-worst step)",
    )
    parser.add_argument(
        "--crowd-bodies",
        nargs="?",
        const="scaled",
        choices=("scaled", "anny"),
        help="also time each crowd with a body per character against one body for all, alternating: "
        "the mannequin scaled 0.9-1.1 (scaled, the default) or anny bodies sampled as the "
        "bodies preset does (anny: the bodies extra)",
    )
    parser.add_argument("--crowd-repeat", type=int, default=3, help="alternations of the --crowd-bodies runs")
    parser.add_argument(
        "--repeat", type=int, default=3, help="timed passes per offline figure (their median)"
    )
    parser.add_argument(
        "--precision",
        choices=PRECISIONS,
        default="float32",
        help="the mesh decoder's arithmetic for batches (crowds, offline); bfloat16 needs AMX",
    )
    parser.add_argument(
        "--push",
        choices=("mesh", "subspace"),
        default="mesh",
        help="the crowds' push-out: mesh, or subspace (the push in the fast decoder's subspace first)",
    )
    parser.add_argument(
        "--decoder",
        choices=("full", "fast"),
        default="full",
        help="the mesh decoder: full, or fast (the subspace decoder; random weights get a random one)",
    )
    parser.add_argument(
        "--device",
        default="native",
        help="where crowds run: native (the CPU kernels, the hybrid) or a torch device such as cuda "
        "(the regression as one torch step)",
    )
    parser.add_argument(
        "--crowd-only", action="store_true", help="only the crowds (no offline or single-stream figures)"
    )
    parser.add_argument("--json", action="store_true", help="one JSON object per resolution, nothing else")
    args = parser.parse_args()
    for v in [None] if args.model else args.vertices:
        r = bench(
            v,
            args.database,
            args.seconds,
            args.model,
            args.motion,
            args.pace,
            args.crowd,
            args.repeat,
            args.precision,
            args.crowd_frames,
            args.crowd_repeat if args.crowd_bodies else 0,
            decoder=args.decoder,
            offline=not args.crowd_only,
            device=args.device,
            push=args.push,
            crowd_bodies_from=args.crowd_bodies or "scaled",
        )
        if args.json:
            print(json.dumps(r))
            continue
        print(
            f"{r['model']}, {r['motion']}: {r['vertices']} vertices, database {r['database_windows']} "
            f"windows, {r['threads']} threads, {r['precision']} {r['decoder']} decoder; peak RSS "
            f"{r['peak_rss_mb']} MB"
        )
        if not args.crowd_only:
            print(
                f"  {r['clip_frames']}-frame clip: offline frames/s hybrid {r['fps_hybrid']}, regression "
                f"{r['fps_regression']}, retrieval {r['fps_retrieval']}, detail {r['fps_detail']} (hybrid "
                f"with push-out {r['fps_hybrid_with_collision']}); streaming p50 {r['stream_p50_ms']} ms, "
                f"p99 {r['stream_p99_ms']} ms (without push-out p50 {r['stream_no_collision_p50_ms']}, p99 "
                f"{r['stream_no_collision_p99_ms']})"
                + (
                    f"; paced at {args.pace:g} frames/s p50 {r['stream_paced_p50_ms']} ms, p99 "
                    f"{r['stream_paced_p99_ms']} ms"
                    if args.pace
                    else ""
                )
            )
            print(
                "  streamed frame, median ms per stage: "
                + ", ".join(f"{k} {v}" for k, v in r["stream_stage_p50_ms"].items())
            )
        print(f"  {r['cpu']}")
        if "reference_ms" in r:
            low, high = r["reference_spread_ms"]
            print(
                f"  budget reference (a 1024 x 1024 float32 matrix product, {r['threads']} threads): "
                f"{r['reference_ms']} ms median of this run ({low}-{high})"
            )
        for n, c in r.get("crowd", {}).items():
            print(
                f"  crowd of {n} ({r['crowd_device']}): step p50 {c['p50_ms']} ms ({c['p50_x']} x the "
                f"reference), p99 {c['p99_ms']} ms ({c['p99_x']} x) "
                f"(paced p50 {c['paced_p50_ms']}, p99 {c['paced_p99_ms']}); {c['per_character_us']} us a "
                f"character, {c['character_frames_per_s']} character-frames/s"
                + (
                    "; median ms per stage: " + ", ".join(f"{k} {v}" for k, v in c["stage_p50_ms"].items())
                    if "stage_p50_ms" in c
                    else ""
                )
            )
        for n, c in r.get("crowd_bodies", {}).items():
            print(
                f"  crowd of {n} on {n} bodies against one body: step p99 ratio {c['p99_ratio_median']} "
                f"(each alternation: {c['p99_ratios']})"
            )


if __name__ == "__main__":
    main()
