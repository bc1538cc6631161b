"""The autoencoder's loss terms and its error measure: uniform Laplacian coordinates (the
smoothness term) and the mean per-vertex error in millimetres."""

from __future__ import annotations

import numpy as np
import torch

from ..models.fcmae import MeshAutoencoder


def laplacian_operator(index: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Sparse (V, V) uniform Laplacian from 1-ring lists whose slot 0 is the vertex itself:
    each vertex minus the mean of its neighbours."""
    v = index.shape[0]
    count = mask[:, 1:].sum(1).clamp(min=1)
    rows = torch.arange(v).unsqueeze(1).expand_as(index[:, 1:])[mask[:, 1:] > 0]
    cols = index[:, 1:][mask[:, 1:] > 0]
    vals = -(1.0 / count).unsqueeze(1).expand_as(index[:, 1:])[mask[:, 1:] > 0]
    i = torch.cat([torch.stack([rows, cols]), torch.arange(v).repeat(2, 1)], 1)
    return torch.sparse_coo_tensor(
        i, torch.cat([vals, torch.ones(v)]), (v, v), check_invariants=True
    ).coalesce()


def apply_laplacian(op: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
    """(B, V, 3) -> (V, B * 3) Laplacian coordinates (vertex-major: a sparse matmul)."""
    return torch.sparse.mm(op, x.transpose(0, 1).reshape(x.shape[1], -1))


def pve_mm(
    model: MeshAutoencoder, frames: np.ndarray, latents: np.ndarray | None = None, batch: int = 64
) -> float:
    """Mean per-vertex Euclidean error (mm) of reconstructing ``frames``: through the encoder, or
    by decoding the given ``latents`` (one per frame)."""
    if len(frames) == 0:
        return float("nan")
    total = 0.0
    device = model.template.device
    with torch.no_grad():
        for i in range(0, len(frames), batch):
            x = torch.from_numpy(frames[i : i + batch]).to(device)
            y = (
                model(x)
                if latents is None
                else model.decode(torch.from_numpy(latents[i : i + batch]).to(device))
            )
            total += float((y - x).norm(dim=-1).mean(1).sum())
    return 1000.0 * total / len(frames)
