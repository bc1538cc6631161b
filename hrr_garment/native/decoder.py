"""ctypes glue of the mesh decoder's kernels (``kernels.c``: the batched block and the factored
single-frame block; ``amx_block.c``: the batched block in bfloat16 on AMX): each block's constants
in the kernels' layouts (:class:`NativeBlock`), bfloat16 rounding and pair-interleaving, and the
last rows turned into frames. Used by :class:`hrr_garment.models.inference_decoder.InferenceDecoder`; the
library from :func:`hrr_garment.native.load_kernel`.

PyTorch runs a spatially varying convolution as a gather (materialising every neighbour's row for
every output vertex: S times the layer's output), a layout copy, then small per-vertex matmuls;
on the CPU that is memory-bound (about 5 % of the matmul peak). This kernel walks the output
vertices once: for each it reads its neighbours' rows in place (vertex-major rows of B x C_in
floats, contiguous), accumulates them through its per-slot kernels into a B x C_out tile that
stays in L1, adds the residual path (the normalised neighbour average read from the same rows,
then the 1x1 map) and the activation, and writes the tile once. Padded neighbour slots are
dropped (compressed rows), which also removes about 40 % of the work.
"""

from __future__ import annotations

import ctypes

import numpy as np

from .panels import PANEL, pack_panels

PRECISIONS = ("float32", "bfloat16")  # the batched decoder's arithmetic (bfloat16: hrr_block_bf16, AMX)

WIDTHS = (8, 16, 32, 64, 128)  # output widths the kernel is specialised for
APPLY_WIDTHS = (4, 8, 16, 32, 64, 128)  # block widths of the single-frame kernel


def _ptr(a: np.ndarray | None, kind=ctypes.c_float):
    return None if a is None else a.ctypes.data_as(ctypes.POINTER(kind))


def bf16_bits(a: np.ndarray) -> np.ndarray:
    """float32 -> bfloat16 bits (uint16), rounded to nearest even as PyTorch rounds."""
    bits = np.ascontiguousarray(a, np.float32).view(np.uint32)
    return ((bits + np.uint32(0x7FFF) + ((bits >> 16) & 1)) >> 16).astype(np.uint16)


def bf16_pairs(m: np.ndarray) -> np.ndarray:
    """Matrices (..., cin, width) float32 -> AMX's pair-interleaved bfloat16 (..., cin / 2, width, 2):
    input rows 2p and 2p + 1 of each column side by side."""
    *lead, cin, width = m.shape
    pairs = bf16_bits(m).reshape(*lead, cin // 2, 2, width)
    return np.ascontiguousarray(np.swapaxes(pairs, -1, -2))


class NativeBlock:
    """One decoder block's constants in the kernel's layout (see ``SOURCE``); ``activation`` is the
    block's (a, b, elu)."""

    def __init__(
        self,
        index: np.ndarray,
        mask: np.ndarray,
        kernel: np.ndarray,
        bias: np.ndarray,
        pool: np.ndarray | None,
        proj: np.ndarray | None,
        activation: tuple[float, float, bool],
    ):
        a, b, elu = activation
        keep = mask > 0  # (V, S): real neighbour slots
        self.offsets = np.concatenate([[0], np.cumsum(keep.sum(1))]).astype(np.int32)
        self.nbr = np.ascontiguousarray(index[keep], np.int32)
        v, s = index.shape
        cin, cout = kernel.shape[1] // s, kernel.shape[2]
        width = next((w for w in WIDTHS if w >= cout), None)
        if width is None:
            raise ValueError(f"the native kernel handles up to {WIDTHS[-1]} output channels, not {cout}")
        pad = [(0, 0)] * 2 + [(0, width - cout)]  # zero columns: the kernel's widths are fixed
        self.kernel = np.ascontiguousarray(
            np.pad(kernel.reshape(v, s, cin, cout)[keep], pad), np.float32
        )  # (nnz, cin, width)
        self.bias = np.ascontiguousarray(np.pad(bias, (0, width - cout)), np.float32)
        self.pool = None if pool is None else np.ascontiguousarray(pool[keep], np.float32)
        if proj is None and width != cout:
            proj = np.eye(cin, cout, dtype=np.float32)
        self.proj = (
            None
            if proj is None
            else np.ascontiguousarray(np.pad(proj, [(0, 0), (0, width - cout)]), np.float32)
        )
        self.cin, self.cout, self.width, self.vertices = cin, cout, width, v
        self.a, self.b, self.elu = float(a), float(b), bool(elu)
        self.factored = None  # (transform (cin, (M + 1) * width), kernel arguments, arrays) via set_factored

    def set_factored(
        self, coeff: np.ndarray, basis: np.ndarray, mask: np.ndarray, proj: np.ndarray | None
    ) -> None:
        """Basis coefficients (V, S, M) and basis (M, cin, cout) for single frames (``one``)."""
        keep = mask > 0
        m, cin, cout = basis.shape
        width = next(w for w in APPLY_WIDTHS if w >= cout)
        proj = np.eye(cin, cout, dtype=np.float32) if proj is None else proj  # identity residual: cin == cout
        # x (Vin, cin) @ transform = [x W_0 | ... | x W_{M-1} | x proj], each block padded to width
        blocks = np.concatenate([basis, proj[None]], 0)  # (M + 1, cin, cout)
        blocks = (
            np.pad(blocks, [(0, 0), (0, 0), (0, width - cout)])
            .transpose(1, 0, 2)
            .reshape(cin, (m + 1) * width)
        )
        coeff = np.ascontiguousarray(coeff[keep], np.float32)
        bias = np.ascontiguousarray(np.pad(self.bias[:cout], (0, width - cout)), np.float32)
        transform = pack_panels(blocks)
        zeros = np.zeros(transform.shape[0] * PANEL, np.float32)  # the product's (absent) bias
        # the constant arguments, converted once: ctypes conversions cost microseconds each, per frame
        constants = (
            transform.ctypes.data,
            zeros.ctypes.data,
            m,
            self.cout,
            width,
            self.vertices,
            self.offsets.ctypes.data,
            self.nbr.ctypes.data,
            coeff.ctypes.data,
            None if self.pool is None else self.pool.ctypes.data,
            bias.ctypes.data,
            ctypes.c_float(self.a),
            ctypes.c_float(self.b),
            int(self.elu),
        )
        self.factored = ((m + 1) * width, constants, (transform, zeros, coeff, bias))

    def one(
        self, lib: ctypes.CDLL, x: np.ndarray, threads: int, scratch: np.ndarray | None = None
    ) -> np.ndarray:
        """One frame: x (V_in, C_in) float32 C-contiguous -> (V, C_out), the same function as
        ``__call__``, in one kernel call (the transform, then the apply). ``scratch``: float32
        room for the transform's V_in x (M + 1) x width product, which a decoder shares among its
        blocks (one buffer stays in cache better than one per block). The result lives in a buffer
        of the block that the next call overwrites (fresh buffers of up to a few MB per frame cost
        more in page faults than the arithmetic): one call at a time per decoder, and copy what you
        keep."""
        row, constants, _ = self.factored  # the last item keeps the arrays behind the pointers alive
        if scratch is None or scratch.size < len(x) * row:
            scratch = np.empty(len(x) * row, np.float32)
        if getattr(self, "_out", None) is None:
            self._out = np.empty((self.vertices, self.cout), np.float32)
        lib.hrr_factor_block(
            x.ctypes.data,
            len(x),
            self.cin,
            constants[0],
            constants[1],
            scratch.ctypes.data,
            *constants[2:],
            threads,
            self._out.ctypes.data,
        )
        return self._out

    def set_bf16(self) -> None:
        """This block's constants in the bfloat16 form of ``hrr_block_bf16`` (``amx_block.c``): kernels
        and the residual's 1x1 map rounded and pair-interleaved, output width a multiple of 16 or a
        narrow 4 or 8."""
        cout = self.cout
        width = next((w for w in (4, 8) if w >= cout), -(-cout // 16) * 16)
        pad = [(0, 0)] * 2 + [(0, width - cout)]
        proj = np.eye(self.cin, cout, dtype=np.float32) if self.proj is None else self.proj[:, :cout]
        kernel = bf16_pairs(np.pad(self.kernel[..., :cout], pad))
        bias = np.ascontiguousarray(np.pad(self.bias[:cout], (0, width - cout)), np.float32)
        self.bf16 = (width, kernel, bf16_pairs(np.pad(proj, pad[1:])), bias)

    def call_bf16(
        self,
        lib: ctypes.CDLL,
        x: np.ndarray,
        threads: int,
        last: bool,
        out: np.ndarray | None = None,
        scratch: np.ndarray | None = None,
    ) -> np.ndarray:
        """x (V_in, Bp, C_in) bfloat16 bits (uint16), Bp a multiple of 16 -> ``out`` (V, Bp, width): the
        next block's bfloat16 input, or float32 for the ``last`` block (``set_bf16`` first).
        ``scratch``: float32 room for V_in x Bp x width (the residual's projection). A decoder
        passes buffers it keeps: fresh ones cost more in page faults than the block."""
        width, kernel, proj, bias = self.bf16
        batch = x.shape[1]
        need = x.shape[0] * batch * width
        scratch = np.empty(need, np.float32) if scratch is None or scratch.size < need else scratch
        if out is None:
            out = np.empty((self.vertices, batch, width), np.float32 if last else np.uint16)
        status = lib.hrr_block_bf16(
            x.ctypes.data,
            batch,
            self.cin,
            width,
            x.shape[0],
            self.vertices,
            self.offsets.ctypes.data,
            self.nbr.ctypes.data,
            kernel.ctypes.data,
            bias.ctypes.data,
            None if self.pool is None else self.pool.ctypes.data,
            proj.ctypes.data,
            self.a,
            self.b,
            int(self.elu),
            threads,
            scratch.ctypes.data,
            None if last else out.ctypes.data,
            out.ctypes.data if last else None,
        )
        if status:
            raise RuntimeError(
                "bfloat16 decoding needs AMX (an Intel Xeon of Sapphire Rapids or newer, on Linux)"
            )
        return out

    def __call__(self, lib: ctypes.CDLL, x: np.ndarray, threads: int, padded: bool = False) -> np.ndarray:
        """x (V_in, B, C_in) float32 C-contiguous -> (V, B, C_out), or with ``padded`` the kernel's
        own (V, B, width) rows, whose columns past C_out are zero (a caller that copies anyway
        slices them itself)."""
        batch = x.shape[1]
        out = np.empty((self.vertices, batch, self.width), np.float32)
        lib.hrr_block(
            _ptr(x),
            batch,
            self.cin,
            self.width,
            self.vertices,
            _ptr(self.offsets, ctypes.c_int32),
            _ptr(self.nbr, ctypes.c_int32),
            _ptr(self.kernel),
            _ptr(self.bias),
            _ptr(self.pool),
            _ptr(self.proj),
            self.a,
            self.b,
            int(self.elu),
            threads,
            _ptr(out),
        )
        return out if padded or self.width == self.cout else np.ascontiguousarray(out[..., : self.cout])


def rows_to_frames(
    lib: ctypes.CDLL, rows: np.ndarray, frames: int, template: np.ndarray, scale: float, threads: int
) -> np.ndarray:
    """A decoder's last block rows (V, Bp, width) float32, C-contiguous -> (frames, V, C) float32
    ``template + scale * rows[:, :frames, :C]`` with C the template's columns."""
    v, padded, width = rows.shape
    out = np.empty((frames, v, template.shape[1]), np.float32)
    lib.hrr_rows_to_frames(
        rows.ctypes.data,
        v,
        padded,
        width,
        frames,
        template.shape[1],
        template.ctypes.data,
        ctypes.c_float(scale),
        threads,
        out.ctypes.data,
    )
    return out
