"""The mesh autoencoder's decoder for inference (:class:`InferenceDecoder`): the basis of every layer
folded into per-vertex kernels once, run by the native kernels (a batched path, and a single-frame
path for streaming), or by the PyTorch blocks without a compiler."""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from .. import native as native_kernel
from ..errors import UnsupportedHardware
from ..native import PRECISIONS
from ..native.decoder import NativeBlock, bf16_bits, rows_to_frames

# Batches smaller than this decode frame by frame through the single-frame path: the batched
# path reads every per-vertex kernel once per call, which pays off from about a dozen frames (on 2
# AMD EPYC cores at 4,156 vertices: one frame 1.8-3.0 ms; batches of 2-8 3.7-6.5 ms a frame,
# of 16 2.2, of 64 1.5)
SINGLE_FRAME_BELOW = 12
# In bfloat16 (AMX) a batch pads to whole tiles of 16 frames and streams all its kernels (62 MB at
# 4,156 vertices) at many times float32's arithmetic rate: from this many frames one padded batch
# beats frames one at a time (on 2 Xeon cores at 4,156 vertices: 8 or 16 frames 3.3 ms, one frame
# 0.95; 32 frames 5.7 against 22 in float32)
BF16_BATCH_FROM = 4


class InferenceDecoder(nn.Module):
    """Inference-only decoder: the same layers with each basis folded into per-vertex kernels and
    each residual average's weights computed once. By default a call runs the fused C kernel of
    :mod:`.native` (compiled on first use; about 5x faster on the CPU); without a C compiler, or
    with ``native=False``, it runs the PyTorch blocks (gathers and batched matmuls). Both equal
    ``MeshAutoencoder.decode`` up to float32 rounding.

    ``precision="bfloat16"`` runs batches of frames (crowds, offline animation) through the AMX tile
    unit (Intel Xeon, Sapphire Rapids or newer): kernels and activations rounded to bfloat16, sums
    in float32; about 3.8x faster on 32 frames, 0.16 mm from float32 on average on a trained dress
    (docs/inference.md). Batches of fewer than ``BF16_BATCH_FROM`` frames stay in float32."""

    def __init__(self, model, native: bool | None = None, cache_dir=None, precision: str = "float32"):
        super().__init__()
        self.blocks = model.decoder
        with torch.no_grad():
            self.kernels = [b.conv.effective_kernel().detach().contiguous() for b in self.blocks]
            self.weights = [
                b.residual.weights().detach() if b.residual.neighbours else None for b in self.blocks
            ]
        self.template, self.scale = model.template, model.scale
        self.latent_nodes = model.latent_shape[0]
        self._template_np = model.template.detach().numpy().astype(np.float32)  # the single-frame path's
        self._scratch: np.ndarray | None = None
        self.lib = native_kernel.load_kernel(cache_dir) if native is not False else None
        if native and self.lib is None:
            raise RuntimeError("the native decoder kernel could not be compiled (is a C compiler installed?)")
        self.native_blocks = (
            []
            if self.lib is None
            else [
                NativeBlock(
                    b.conv.index.numpy(),
                    b.conv.mask.numpy(),
                    k.numpy(),
                    bias=b.conv.bias.detach().numpy(),
                    pool=None if w is None else w.numpy(),
                    proj=None if b.residual.project is None else b.residual.project.weight.detach().T.numpy(),
                    activation=(b.a, b.b, b.activation),
                )
                for b, k, w in zip(self.blocks, self.kernels, self.weights)
            ]
        )
        if precision not in PRECISIONS:
            raise ValueError(f"precision must be one of {', '.join(PRECISIONS)}, not {precision!r}")
        self.precision = precision
        if precision == "bfloat16":
            if self.lib is None or not self.lib.hrr_amx_ready():
                raise UnsupportedHardware(
                    "precision='bfloat16' needs the native kernel on a CPU with AMX (an Intel Xeon "
                    "of Sapphire Rapids or newer, on Linux); this machine decodes in float32 only"
                )
            for nb in self.native_blocks:
                nb.set_bf16()
        self._bf16_buffers: tuple[int, list[np.ndarray]] | None = None
        with torch.no_grad():
            for nb, b in zip(self.native_blocks, self.blocks):
                nb.set_factored(
                    (b.conv.coeff * b.conv.mask.unsqueeze(-1)).numpy(),
                    b.conv.weight.detach().numpy(),
                    b.conv.mask.numpy(),
                    None if b.residual.project is None else b.residual.project.weight.detach().T.numpy(),
                )

    @property
    def native(self) -> bool:
        return bool(self.native_blocks)

    def compiled(self):
        """The PyTorch path through torch.compile (Inductor fuses the gathers with the layout
        copies): about 1.9x faster than the plain PyTorch path, slower than the native kernel;
        the first call per batch shape compiles for about a minute."""
        return torch.compile(self._torch_forward, dynamic=False)

    @torch.no_grad()
    def forward(self, latents: torch.Tensor) -> torch.Tensor:
        """(B, N, 8) latents -> (B, V, 3) heading-frame vertices."""
        if not self.native_blocks:
            return self._torch_forward(latents)
        threads = torch.get_num_threads()
        if self.precision == "bfloat16" and len(latents) >= BF16_BATCH_FROM:
            return self._forward_bf16(latents, threads)
        if 1 < len(latents) < SINGLE_FRAME_BELOW:  # a few frames (a small crowd): one at a time is faster
            return torch.cat(
                [self.forward(latents[i : i + 1]) for i in range(len(latents))]
            )  # each a fresh array
        if len(latents) == 1:  # one frame (streaming): the factored form reads far less memory
            x = np.ascontiguousarray(latents.detach()[0].to(torch.float32).numpy())
            if self._scratch is None:  # the largest transform product of any block, shared
                sizes = [len(x)] + [b.vertices for b in self.native_blocks[:-1]]
                self._scratch = np.empty(
                    max(n * b.factored[0] for n, b in zip(sizes, self.native_blocks)), np.float32
                )
            for block in self.native_blocks:
                x = block.one(self.lib, x, threads, self._scratch)
            # numpy, not torch, for the last step: PyTorch's per-operator overhead is a tenth of a
            # millisecond here
            return torch.from_numpy((x * np.float32(self.scale) + self._template_np)[None])
        x = np.ascontiguousarray(latents.detach().to(torch.float32).transpose(0, 1).numpy())
        for block in self.native_blocks[:-1]:
            x = block(self.lib, x, threads)
        x = self.native_blocks[-1](self.lib, x, threads, padded=True)  # (V, B, width >= 3)
        # frames first and contiguous in one pass that reads the padded rows where they lie: slicing,
        # transposing and scaling one after another took 2.8 ms of a 64-character crowd's frame
        return torch.from_numpy(
            rows_to_frames(
                self.lib,
                x,
                len(latents),
                template=self._template_np,
                scale=float(self.scale),
                threads=threads,
            )
        )

    def _forward_bf16(self, latents: torch.Tensor, threads: int) -> torch.Tensor:
        batch = len(latents)
        x, *outs, scratch = self._buffers_bf16(-(-batch // 16) * 16)
        # padding frames keep whatever an earlier call left there: every frame is decoded on its own
        x[:, :batch] = bf16_bits(latents.detach().to(torch.float32).transpose(0, 1).numpy())
        for i, (block, out) in enumerate(zip(self.native_blocks, outs)):
            x = block.call_bf16(self.lib, x, threads, i == len(outs) - 1, out, scratch)
        return torch.from_numpy(
            rows_to_frames(
                self.lib, x, batch, template=self._template_np, scale=float(self.scale), threads=threads
            )
        )

    def _buffers_bf16(self, padded: int) -> list[np.ndarray]:
        """The bfloat16 path's input, each block's output and the shared projection room, for
        ``padded`` frames, kept between calls (one call at a time per decoder)."""
        if self._bf16_buffers is None or self._bf16_buffers[0] != padded:
            blocks = self.native_blocks
            x = np.zeros((self.latent_nodes, padded, blocks[0].cin), np.uint16)
            outs = [
                np.zeros((b.vertices, padded, b.bf16[0]), np.float32 if i == len(blocks) - 1 else np.uint16)
                for i, b in enumerate(blocks)
            ]
            inputs = [len(x)] + [b.vertices for b in blocks[:-1]]
            scratch = np.zeros(max(n * padded * b.bf16[0] for n, b in zip(inputs, blocks)), np.float32)
            self._bf16_buffers = (padded, [x, *outs, scratch])
        return self._bf16_buffers[1]

    @torch.no_grad()
    def _torch_forward(self, latents: torch.Tensor) -> torch.Tensor:
        x = latents.transpose(0, 1)
        for block, kernel, weights in zip(self.blocks, self.kernels, self.weights):
            x = block(x, kernel, weights)
        return x.transpose(0, 1) * self.scale + self.template
