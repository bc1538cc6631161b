"""The code space's window step in C: :class:`NativeWindowCodes` computes what
:class:`.codes.WindowCodes` computes (motion encoder -> per-group entropy and
argmax -> the regression's embedding -> the code-space decoder), from the same weights, with the kernel in
``window_codes.c``.

Used for causal inference, streaming and offline alike, so both run the same arithmetic: a stream
pushes one window per frame, where PyTorch's per-operator overhead is most of the time (1.5-3 ms
per window against about 0.5 ms here, where the threads share the window's work). Offline, the
windows run in lockstep passes of up to 64, each layer once for all of them. Causal paths pass each
frame's GRU input gates, computed once as the frame came (:meth:`NativeWindowCodes.frame_gates`).
The offline non-causal engine keeps PyTorch, whose batched matrix
products are faster over many windows. Results equal PyTorch's up to float32 rounding (tested); an
argmax can only differ where two logits tie to rounding.
"""

from __future__ import annotations

import ctypes

import numpy as np
import torch

from .. import native


def pack_linear(weight: np.ndarray, bias: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A PyTorch linear layer's weight (out, in) and bias (out,) in the kernels' layout: W^T in
    panels (:func:`hrr_garment.native.pack_panels`) and the bias zero-padded to whole panels."""
    return native.pack_panels(weight.T), np.ascontiguousarray(
        np.pad(bias, (0, -len(bias) % native.PANEL)), np.float32
    )


class NativeWindowCodes:
    """Standardised windows (B, W, F) -> (entropy (B,), argmax classes (B, G) int64, regressed
    standardised latents (B, W or 1, nodes, C), or an empty tensor without ``regression``).
    ``lib``: the loaded kernel library (:func:`hrr_garment.native.load_kernel`). The weights are copied into
    the kernel's layout when it is made: make a new one after changing the networks."""

    def __init__(self, codespace, lib: ctypes.CDLL, regression: bool = True, last_frame: bool = False):
        enc, q, cfg = codespace.motion_encoder, codespace.quantizer, codespace.config
        for attention in (enc.attention, enc.pool):
            if (
                not attention._qkv_same_embed_dim
                or attention.in_proj_bias is None
                or attention.bias_k is not None
            ):
                raise ValueError(
                    "the native window step handles attention with packed, biased projections only"
                )
        gru = enc.gru
        if gru.num_layers != 1 or gru.bidirectional or not gru.bias:
            raise ValueError("the native window step handles a one-layer, one-direction GRU with biases only")
        linears = [m for m in codespace.decoder.net if isinstance(m, torch.nn.Linear)]
        self.lib, self.regression, self.last_frame = lib, regression, last_frame
        self.window, self.latent_shape = cfg.window, codespace.latent_shape
        self.rows = (1 if last_frame else cfg.window) * self.latent_shape[0] * self.latent_shape[1]
        out_norm, out_linear = enc.out
        h = cfg.motion_hidden

        def linear(weight, bias):
            return list(pack_linear(weight.detach().numpy(), bias.detach().numpy()))

        weights = [
            *linear(enc.inp.weight, enc.inp.bias),
            *linear(gru.weight_ih_l0, gru.bias_ih_l0),
            *linear(gru.weight_hh_l0, gru.bias_hh_l0),
            *linear(enc.attention.in_proj_weight, enc.attention.in_proj_bias),
            *linear(enc.attention.out_proj.weight, enc.attention.out_proj.bias),
            enc.norm.weight,
            enc.norm.bias,
            enc.query.reshape(-1),
            *linear(enc.pool.in_proj_weight[:h], enc.pool.in_proj_bias[:h]),
            *linear(enc.pool.in_proj_weight[h:], enc.pool.in_proj_bias[h:]),
            *linear(enc.pool.out_proj.weight, enc.pool.out_proj.bias),
            out_norm.weight,
            out_norm.bias,
            *linear(out_linear.weight, out_linear.bias),
            q.embedding,
            torch.tensor([enc.norm.eps, out_norm.eps]),
        ]
        # a model across bodies or cloths: their values after the embedding
        sizes = [q.embedding_size + cfg.condition_features]
        for i, layer in enumerate(linears):
            last = i == len(linears) - 1  # causal inference needs only the last frame's rows
            weights += (
                linear(layer.weight[-self.rows :], layer.bias[-self.rows :])
                if last
                else linear(layer.weight, layer.bias)
            )
            sizes.append(self.rows if last else layer.out_features)
        self._arrays = [
            np.ascontiguousarray(w.detach().numpy() if isinstance(w, torch.Tensor) else w, np.float32)
            for w in weights
        ]  # kept alive: the kernel reads them through pointers
        self._pointers = (ctypes.c_void_p * len(self._arrays))(*[a.ctypes.data for a in self._arrays])
        self._dims = np.array(
            [
                codespace.features,
                cfg.window,
                cfg.motion_hidden,
                cfg.attention_heads,
                q.groups,
                q.classes,
                q.dim,
                len(linears),
                *sizes,
                int(cfg.regression_code == "expected"),
                cfg.condition_features,
            ],
            np.int32,
        )
        self.groups = q.groups

    @property
    def gate_width(self) -> int:
        """Floats of one frame's GRU input gates (3 x the motion encoder's width)."""
        return 3 * int(self._dims[2])

    def frame_gates(self, frames: np.ndarray) -> np.ndarray:
        """Standardised frames (n, F) -> their GRU input gates (n, :attr:`gate_width`): the motion
        encoder's input layer and the GRU's input side, a function of each frame alone. A stream keeps
        them per frame and passes each window's to :meth:`__call__`, which then skips them (about a
        quarter of the window step's arithmetic); the bits are those the step computes itself."""
        x = np.ascontiguousarray(frames, np.float32)
        gates = np.empty((len(x), self.gate_width), np.float32)
        if self.lib.hrr_frame_gates(
            x.ctypes.data,
            len(x),
            self._dims.ctypes.data,
            ctypes.addressof(self._pointers),
            torch.get_num_threads(),
            gates.ctypes.data,
        ):
            raise MemoryError("the native window step could not allocate its scratch memory")
        return gates

    def __call__(
        self, windows: torch.Tensor, gates: np.ndarray | None = None
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """``windows``: (B, W, F) standardised; ``gates``: (B, W, :attr:`gate_width`) the windows'
        frames' :meth:`frame_gates`, where kept; with them only each window's last frame is read
        (``windows`` may be that frame alone, (B, 1, F))."""
        x = windows.detach().numpy()
        b, window = len(x), int(self._dims[1])
        if gates is not None:
            x = x[:, -1:]
            gates = np.ascontiguousarray(gates, np.float32)
            if gates.shape != (b, window, self.gate_width):
                raise ValueError(
                    f"gates of shape {gates.shape} for {b} windows of {window} frames "
                    f"(expected {(b, window, self.gate_width)})"
                )
        x = np.ascontiguousarray(x, np.float32)
        entropy, argmax = np.empty(b, np.float32), np.empty((b, self.groups), np.int64)
        latents = np.empty((b, self.rows), np.float32) if self.regression else None
        failed = self.lib.hrr_window_codes(
            x.ctypes.data,
            None if gates is None else gates.ctypes.data,
            b,
            self._dims.ctypes.data,
            ctypes.addressof(self._pointers),
            torch.get_num_threads(),
            entropy.ctypes.data,
            argmax.ctypes.data,
            None if latents is None else latents.ctypes.data,
        )
        if failed:
            raise MemoryError("the native window step could not allocate its scratch memory")
        reg = (
            torch.empty(0)
            if latents is None
            else torch.from_numpy(latents.reshape(b, -1, *self.latent_shape))
        )
        return torch.from_numpy(entropy), torch.from_numpy(argmax), reg


def native_window_codes(
    codespace, regression: bool = True, last_frame: bool = False
) -> NativeWindowCodes | None:
    """The native window step, or None where the kernel is unavailable (no C compiler, or
    ``HRR_NATIVE=0``) or the networks are of a shape it does not handle."""
    lib = native.load_kernel()
    if lib is None:
        return None
    try:
        return NativeWindowCodes(codespace, lib, regression, last_frame)
    except ValueError:
        return None
