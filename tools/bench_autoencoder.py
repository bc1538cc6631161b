"""Benchmark: batched decoding speed of the mesh autoencoder's fast path (the native C kernel).

For each template resolution (the dress at about 4,000 and 12,000 vertices by default; random
weights: speed does not depend on them) it decodes batches of latents with ``inference_decoder()`` and
reports decoded frames per second, the model's FLOPs per frame (counted from the layer shapes:
2 x multiply-adds of every kernel product, residual average and 1x1 map), the achieved GFLOP/s,
and the same machine's float32 matrix-multiply rate (a 2048^3 torch.mm) as the peak to compare with.

    python tools/bench_autoencoder.py                    # 4,000 and 12,000 vertices
    python tools/bench_autoencoder.py --vertices 4000 --json
    python tools/bench_autoencoder.py --torch --compile  # also the PyTorch path, plain and compiled
"""

from __future__ import annotations

import argparse
import json
import time

import torch

from hrr_garment.garment.templates import make_garment
from hrr_garment.models.fcmae import AutoencoderSettings, MeshAutoencoder
from hrr_garment.models.hierarchy import build_hierarchy


def decoder_flops(model: MeshAutoencoder) -> int:
    """Useful floating-point operations to decode one frame (real neighbours only, not padding)."""
    total = 0
    for block in model.decoder:
        v = block.conv.index.shape[0]
        pairs = int(block.conv.mask.sum())  # (output vertex, real neighbour) pairs
        cin, cout = block.conv.weight.shape[1:]
        total += 2 * pairs * cin * cout + 2 * v * cout  # kernel products and bias
        if block.residual.neighbours:
            total += 2 * int(block.residual.mask.sum()) * cin
        if block.residual.project is not None:
            total += 2 * v * cin * cout
        total += 3 * v * cout  # activation and the residual mix
    return total


def matmul_peak(size: int = 2048, repeat: int = 5) -> float:
    a, b = torch.randn(size, size), torch.randn(size, size)
    torch.mm(a, b)
    t0 = time.perf_counter()
    for _ in range(repeat):
        torch.mm(a, b)
    return 2 * size**3 * repeat / (time.perf_counter() - t0) / 1e9


def _rate(decode, z: torch.Tensor, seconds: float) -> float:
    decode(z)  # warm-up (and compilation, for the compiled decoder)
    frames, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        decode(z)
        frames += len(z)
    return frames / (time.perf_counter() - t0)


def bench(vertices: int, batch: int, seconds: float, compiled: bool, torch_path: bool) -> dict:
    garment = make_garment("dress", vertices)
    model = MeshAutoencoder(
        build_hierarchy(garment.faces, garment.num_vertices), AutoencoderSettings(), garment.vertices
    ).eval()
    fast = model.inference_decoder()
    z = torch.randn(batch, *model.latent_shape)
    with torch.no_grad():
        max_diff = float(
            (fast(z) - model.decode(z)).abs().max()
        )  # the fast path must equal the training path
    fps = _rate(fast, z, seconds)
    extra = (
        {"torch_frames_per_s": round(_rate(model.inference_decoder(native=False), z, seconds), 1)}
        if torch_path
        else {}
    )
    flops = decoder_flops(model)
    return {
        "vertices": garment.num_vertices,
        "levels": list(model.hierarchy.sizes),
        "latent": list(model.latent_shape),
        "backend": "native" if fast.native else "torch",
        "max_abs_diff_vs_training_path": max_diff,
        **extra,
        "batch": batch,
        "threads": torch.get_num_threads(),
        "frames_per_s": round(fps, 1),
        "ms_per_frame": round(1000 / fps, 3),
        "mflop_per_frame": round(flops / 1e6, 2),
        "gflops": round(flops * fps / 1e9, 2),
        **(_compiled(fast, z, seconds) if compiled else {}),
    }


def _compiled(fast, z: torch.Tensor, seconds: float) -> dict:
    decode = fast.compiled()
    diff = float((decode(z) - fast._torch_forward(z)).abs().max())
    return {"compiled_frames_per_s": round(_rate(decode, z, seconds), 1), "compiled_max_abs_diff": diff}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--vertices", type=int, nargs="+", default=[4000, 12000])
    parser.add_argument("--batch", type=int, default=64)
    parser.add_argument("--seconds", type=float, default=5.0, help="timing window per resolution")
    parser.add_argument("--json", action="store_true", help="one JSON object per resolution, nothing else")
    parser.add_argument(
        "--compile", action="store_true", help="also time the torch.compile'd PyTorch path (compiles ~1 min)"
    )
    parser.add_argument(
        "--torch",
        action="store_true",
        help="also time the plain PyTorch path (what runs without a C compiler)",
    )
    args = parser.parse_args()
    peak = matmul_peak()
    for v in args.vertices:
        result = bench(v, args.batch, args.seconds, args.compile, args.torch)
        result["matmul_peak_gflops"] = round(peak, 1)
        result["fraction_of_peak"] = round(result["gflops"] / peak, 3)
        if args.json:
            print(json.dumps(result))
        else:
            print(
                f"{result['vertices']} vertices (levels {result['levels']}), {result['backend']} decoder: "
                f"{result['frames_per_s']} frames/s ({result['ms_per_frame']} ms/frame, batch {args.batch}, "
                f"{result['threads']} threads); {result['mflop_per_frame']} MFLOP/frame -> "
                f"{result['gflops']} GFLOP/s = {100 * result['fraction_of_peak']:.1f} % of the {peak:.0f} "
                "GFLOP/s matmul peak"
                + (f"; PyTorch path: {result['torch_frames_per_s']} frames/s" if args.torch else "")
                + (
                    f"; compiled PyTorch path: {result['compiled_frames_per_s']} frames/s"
                    if args.compile
                    else ""
                )
                + f"; max |fast - training path| {result['max_abs_diff_vs_training_path']:.1e}"
            )


if __name__ == "__main__":
    main()
