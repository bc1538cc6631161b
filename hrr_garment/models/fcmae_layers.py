"""The FCMAE's layers: :class:`VcConv`, the spatially varying convolution (each output vertex its
own neighbour list and its own mix of the layer's shared basis kernels), :class:`ResidualPool`, the
residual path, and :class:`Block`, the two together. Tensors are vertex-major, (V, B, C)
(:mod:`.fcmae` says why)."""

from __future__ import annotations

import math

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

from .hierarchy import Neighbourhoods


def gather_rows(x: torch.Tensor, index: torch.Tensor) -> torch.Tensor:
    """x (V_in, B, C) -> (V_out, S, B, C): the rows of x at ``index`` (V_out, S)."""
    return torch.index_select(x, 0, index.reshape(-1)).reshape(*index.shape, *x.shape[1:])


class VcConv(nn.Module):
    """Spatially varying convolution from one vertex set to another (see module docstring)."""

    def __init__(self, neighbours: Neighbourhoods, in_channels: int, out_channels: int, basis: int):
        super().__init__()
        # derived from the template (rebuilt with the hierarchy), so not part of the saved weights
        self.register_buffer("index", torch.as_tensor(neighbours.index, dtype=torch.long), persistent=False)
        self.register_buffer("mask", torch.as_tensor(neighbours.mask, dtype=torch.float32), persistent=False)
        slots = self.mask.sum(1).clamp(min=1).unsqueeze(1)  # neighbours per output vertex
        self.weight = nn.Parameter(torch.randn(basis, in_channels, out_channels) / math.sqrt(in_channels))
        self.coeff = nn.Parameter(
            torch.randn(*neighbours.index.shape, basis) / math.sqrt(basis) / slots.sqrt().unsqueeze(-1)
        )
        self.bias = nn.Parameter(torch.zeros(out_channels))

    def gather(self, x: torch.Tensor) -> torch.Tensor:
        return gather_rows(x, self.index)

    def forward(
        self, x: torch.Tensor, kernel: torch.Tensor | None = None, gathered: torch.Tensor | None = None
    ) -> torch.Tensor:
        """x (V_in, B, C_in) vertex-major -> (V_out, B, C_out). ``kernel``: a precomputed
        ``effective_kernel()`` (inference); training folds the basis in on every call.
        ``gathered``: ``gather(x)`` when the caller has it already."""
        g = self.gather(x) if gathered is None else gathered
        v, b = g.shape[0], g.shape[2]
        g = g.permute(0, 2, 1, 3).reshape(v, b, -1)  # (V_out, B, S * C_in)
        k = self.effective_kernel() if kernel is None else kernel
        return torch.baddbmm(self.bias.expand(v, 1, -1), g, k)

    def effective_kernel(self) -> torch.Tensor:
        """(V_out, S * C_in, C_out): the basis folded into one kernel per output vertex."""
        coeff = self.coeff * self.mask.unsqueeze(-1)
        k = torch.einsum("vsm,mcd->vscd", coeff, self.weight)
        return k.reshape(k.shape[0], -1, k.shape[-1])


class ResidualPool(nn.Module):
    """Learned normalised neighbour average (when vertex sets differ), then 1x1 map if channels differ."""

    def __init__(self, neighbours: Neighbourhoods | None, in_channels: int, out_channels: int):
        super().__init__()
        self.neighbours = neighbours is not None
        if self.neighbours:
            self.register_buffer(
                "index", torch.as_tensor(neighbours.index, dtype=torch.long), persistent=False
            )
            self.register_buffer(
                "mask", torch.as_tensor(neighbours.mask, dtype=torch.float32), persistent=False
            )
            self.logits = nn.Parameter(torch.zeros(neighbours.index.shape))
        self.project = (
            nn.Linear(in_channels, out_channels, bias=False) if in_channels != out_channels else None
        )

    def weights(self) -> torch.Tensor:
        """(V_out, S), non-negative, each row summing to 1 over the real neighbours."""
        w = torch.exp(self.logits) * self.mask
        return w / w.sum(1, keepdim=True)

    def forward(
        self, x: torch.Tensor, weights: torch.Tensor | None = None, gathered: torch.Tensor | None = None
    ) -> torch.Tensor:
        """x (V_in, B, C_in) -> (V_out, B, C_out). ``gathered``: x's rows at ``index``,
        (V_out, S, B, C_in), when the caller has them already."""
        if self.neighbours:
            v, s = self.index.shape
            if gathered is None:
                gathered = gather_rows(x, self.index)
            w = self.weights() if weights is None else weights
            x = torch.bmm(w.unsqueeze(1), gathered.reshape(v, s, -1)).reshape(v, *x.shape[1:])
        return self.project(x) if self.project is not None else x


class Block(nn.Module):
    """One FCMAE block: a spatially varying convolution with a residual path, then pooling or unpooling."""

    def __init__(
        self,
        conv_nb: Neighbourhoods,
        pool_nb: Neighbourhoods | None,
        channels: tuple[int, int],
        *,
        basis: int,
        residual: float,
        activation: bool = True,
    ):
        """``channels``: (in, out)."""
        super().__init__()
        cin, cout = channels
        self.conv = VcConv(conv_nb, cin, cout, basis)
        self.residual = ResidualPool(pool_nb, cin, cout)
        self.activation = activation
        self.a, self.b = math.sqrt(1.0 - residual), math.sqrt(residual)
        # down and up blocks average over the conv's own neighbourhoods: gather once for both
        # (the second gather and its backward scatter: about 4 % of a quick-dress training step)
        self.shared_gather = (
            pool_nb is not None
            and np.array_equal(pool_nb.index, conv_nb.index)
            and np.array_equal(pool_nb.mask, conv_nb.mask)
        )

    def forward(
        self, x: torch.Tensor, kernel: torch.Tensor | None = None, weights: torch.Tensor | None = None
    ) -> torch.Tensor:
        gathered = self.conv.gather(x) if self.shared_gather else None
        y = self.conv(x, kernel, gathered)
        if self.activation:
            y = F.elu(y)
        return self.a * y + self.b * self.residual(x, weights, gathered)
