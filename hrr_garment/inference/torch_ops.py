"""Tensor operations the exportable stream step's modules share (:mod:`.torch_step`,
:mod:`.torch_push_out`, :mod:`.torch_subspace_push`), written in the operators ONNX has: arrays
held as graph constants, the turn about +Y and a batched solve of symmetric positive definite
systems (``torch.linalg.solve`` has no ONNX form); the loops and conditionals are
:mod:`hrr_garment.models.graph_loops`'s."""

from __future__ import annotations

import numpy as np
import torch
from torch import nn
from torch._higher_order_ops.while_loop import while_loop


def constant(module: nn.Module, name: str, value, dtype=torch.float32) -> None:
    """``value`` as a buffer of ``module`` that the exported graph holds as a constant."""
    module.register_buffer(name, torch.as_tensor(np.asarray(value), dtype=dtype), persistent=False)


def spd_solve(system: torch.Tensor, rhs: torch.Tensor) -> torch.Tensor:
    """x with ``system`` @ x = ``rhs`` for a batch of symmetric positive definite systems (N, k, k)
    and right-hand sides (N, k), in the operators ONNX has (``torch.linalg.solve`` has no ONNX
    form): the Cholesky factor built a column at a time, then the two triangular substitutions, each
    an ONNX ``Loop`` over the k columns. Each step works on whole rows, the entries not yet found
    being zero, so that its one-hot picks need no slice of a size that changes."""
    k = rhs.shape[-1]
    index = torch.arange(k, device=rhs.device)
    start = torch.zeros((), dtype=torch.int64, device=rhs.device)

    def pick(j):
        return (index == j).to(rhs.dtype)  # e_j

    def factor(j, lower):  # column j of the factor: (A e_j - L L_j.) / sqrt(its diagonal), from row j down
        e = pick(j)
        column = system @ e - (lower @ (e @ lower)[..., None])[..., 0]
        column = column / torch.sqrt((column * e).sum(-1, keepdim=True)) * (index >= j).to(rhs.dtype)
        return j + 1, lower + column[:, :, None] * e

    def forward(i, y):  # y_i = (b_i - L_i. y) / L_ii, the later entries of y still zero
        e = pick(i)
        row = e @ lower
        return i + 1, y + e * (((rhs * e).sum(-1) - (row * y).sum(-1)) / (row * e).sum(-1))[:, None]

    def backward(i, x):  # x_j = (y_j - L_.j x) / L_jj, from the last unknown up (j = k - 1 - i)
        e = pick(k - 1 - i)
        column = (lower @ e[:, None])[..., 0]
        return i + 1, x + e * (((y * e).sum(-1) - (column * x).sum(-1)) / (column * e).sum(-1))[:, None]

    _, lower = while_loop(lambda j, lower: j < k, factor, (start, torch.zeros_like(system)))
    _, y = while_loop(lambda i, y: i < k, forward, (start, torch.zeros_like(rhs)))
    _, x = while_loop(lambda i, x: i < k, backward, (start, torch.zeros_like(rhs)))
    return x


def turn_y(points: torch.Tensor, cos: torch.Tensor, sin: torch.Tensor) -> torch.Tensor:
    """(N, ..., 3) points turned about +Y by angles given as (N,) cosines and sines."""
    shape = (-1,) + (1,) * (points.dim() - 2)
    c, s = cos.reshape(shape), sin.reshape(shape)
    x, y, z = points[..., 0], points[..., 1], points[..., 2]
    return torch.stack([c * x + s * z, y, c * z - s * x], -1)
