"""The push in the garment's subspace (:class:`~.subspace_push.SubspacePush`, docs/decisions/0032)
as a PyTorch module, the first step of :class:`~.torch_push_out.PushOutStage` where the run asks for
it: a batched solve when running (a GPU crowd's), a Cholesky factorisation in ONNX loops when
exporting (:func:`~.torch_ops.spd_solve`, since ONNX has no solve)."""

from __future__ import annotations

import torch
from torch import nn

from .subspace_push import SubspacePush
from .torch_ops import constant, spd_solve, turn_y


class SubspacePushStage(nn.Module):
    """:class:`~.subspace_push.SubspacePush` (its reference, float64, frame by frame) for a batch of
    frames in one graph: every vertex's row of the normal equations, weighted zero outside the band
    near the body (the reference keeps only the rows inside it: the same sums), one batched solve."""

    def __init__(self, push: SubspacePush, margin: float):
        super().__init__()
        constant(self, "basis", push.basis)  # (k, V, 3)
        constant(self, "regulariser", push.strain_weight * push.stretch)  # (k, k)
        self.ridge, self.clearance, self.iterations = (
            float(push.ridge),
            float(push.clearance),
            int(push.iterations),
        )
        self.reach = float(margin) + self.clearance

    def forward(
        self,
        p: torch.Tensor,
        a: torch.Tensor,
        b: torch.Tensor,
        heading: tuple[torch.Tensor, torch.Tensor],
        distance,
    ) -> torch.Tensor:
        """``p`` (N, V, 3) world points and capsule ends ``a``, ``b`` (relative to the pelvis), each
        frame's body-frame ``heading`` (cosines, sines of its yaw), ``distance``
        (:meth:`PushOutStage.distance`)."""
        cos, sin = heading
        eye = torch.eye(self.basis.shape[0], dtype=p.dtype, device=p.device)
        for _ in range(self.iterations):
            d, n = distance(p, a, b)
            depth = self.reach - d
            weight = torch.where(
                depth > 0, torch.clamp(depth / self.clearance, max=1.0), torch.zeros_like(depth)
            )
            jac = torch.einsum(
                "nvi,kvi->nvk", turn_y(n, cos, -sin), self.basis
            )  # the normals in the body frame
            weighted = jac * weight[..., None]
            near = (weight > 0).any(1)[:, None, None]
            system = (
                weighted.transpose(1, 2) @ jac
                + self.regulariser
                + self.ridge * weight.sum(1)[:, None, None] * eye
            )
            system = torch.where(near, system, eye)  # a frame with nothing near stays as it is
            rhs = (weighted * depth[..., None]).sum(1)
            solve = (
                spd_solve if torch.compiler.is_compiling() else torch.linalg.solve
            )  # exporting: no ONNX solve
            coef = solve(system, rhs) * near[:, :, 0]
            p = p + turn_y(torch.einsum("nk,kvi->nvi", coef, self.basis), cos, sin)
        return p
