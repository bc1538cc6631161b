"""Triangle-mesh geometry in torch, in the operators ONNX has, each the twin of a numpy function of
:mod:`hrr_garment.body.mesh_distance` (so that float64 answers agree to rounding): the point of a
triangle nearest to a point, and a mesh's pseudonormals. Differentiable: every division's
denominator is kept off zero in the branches ``where`` drops, so that their gradients stay finite.

The nearest point takes its vectors component-major, (3, ...): each product and sum then runs over
whole contiguous arrays, several times faster on a CPU than reductions over a last axis of three."""

from __future__ import annotations

import torch


def dot(u: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """The dot products of component-major vectors (3, ...)."""
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


def cross(u: torch.Tensor, v: torch.Tensor, dim: int = -1) -> torch.Tensor:
    """u x v over axis ``dim`` (the last, as numpy writes it; 0 for component-major vectors)
    (``torch.linalg.cross`` has no ONNX form)."""
    u0, u1, u2 = u.unbind(dim)
    v0, v1, v2 = v.unbind(dim)
    return torch.stack([u1 * v2 - u2 * v1, u2 * v0 - u0 * v2, u0 * v1 - u1 * v0], dim)


def closest_on_triangles(points: torch.Tensor, triangles: torch.Tensor) -> torch.Tensor:
    """(3, ...) barycentric coordinates of the point of each triangle nearest to each point, for
    component-major points (3, ...) and triangles (3 corners, 3, ...), broadcast against each other
    (:func:`~hrr_garment.body.mesh_distance.closest_on_triangles` step for step: Ericson's cases
    all computed, the first that holds written last)."""
    a, b, c = triangles[0], triangles[1], triangles[2]
    ab, ac, ap, bp, cp = b - a, c - a, points - a, points - b, points - c
    products = dot(ab, ap), dot(ac, ap), dot(ab, bp), dot(ac, bp), dot(ab, cp), dot(ac, cp)
    return torch.stack(_ericson(*products, with_u=True))


def closest_in_plane(
    d1: torch.Tensor, d2: torch.Tensor, *, aa: torch.Tensor, bc: torch.Tensor, cc: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """The nearest point of triangles a, b, c to points p as ``a + v (b - a) + w (c - a)``: (v, w),
    from the products d1 = ab.ap and d2 = ac.ap with the triangles' own ab.ab, ab.ac and ac.ac
    (:func:`closest_on_triangles`'s cases, its four other products from these: a crowd's faces
    computed once, each point and face then two products). Equal to it up to rounding: for ranking
    faces, the chosen one's point found again by :func:`closest_on_triangles`."""
    return _ericson(d1, d2, d1 - aa, d2 - bc, d1 - bc, d2 - cc, with_u=False)[1:]


def _ericson(d1, d2, d3, d4, d5, d6, *, with_u: bool) -> tuple:
    """(u, v, w) of the nearest point from Ericson's six products (ab.ap, ac.ap, ab.bp, ac.bp,
    ab.cp, ac.cp), u left None unless asked (a ranking needs v and w alone)."""
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    total = va + vb + vc
    safe = torch.where(total != 0, total, 1.0)
    v, w = vb / safe, vc / safe
    u = 1.0 - v - w if with_u else None  # the face's interior; the edges and corners below win
    den = (d4 - d3) + (d5 - d6)
    t = (d4 - d3) / torch.where(den != 0, den, 1.0)
    s_ac = d2 / torch.where(d2 != d6, d2 - d6, 1.0)
    s_ab = d1 / torch.where(d1 != d3, d1 - d3, 1.0)
    cases = [
        ((va <= 0) & (d4 >= d3) & (d5 >= d6), (0.0, 1.0 - t, t)),  # edge BC
        ((vb <= 0) & (d2 >= 0) & (d6 <= 0), (1.0 - s_ac, 0.0, s_ac)),  # edge AC
        ((d6 >= 0) & (d5 <= d6), (0.0, 0.0, 1.0)),  # corner C
        ((vc <= 0) & (d1 >= 0) & (d3 <= 0), (1.0 - s_ab, s_ab, 0.0)),  # edge AB
        ((d3 >= 0) & (d4 <= d3), (0.0, 1.0, 0.0)),  # corner B
        ((d1 <= 0) & (d2 <= 0), (1.0, 0.0, 0.0)),  # corner A
    ]
    # Ericson's tests in reverse: the first that holds is the last written (a component at a time:
    # no stacked temporaries)
    for mask, (cu, cv, cw) in cases:
        if with_u:
            u = torch.where(mask, cu, u)
        v, w = torch.where(mask, cv, v), torch.where(mask, cw, w)
    return u, v, w


def pseudo_normals(vertices: torch.Tensor, faces: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """(B, F, 3) unit face normals and (B, V, 3) angle-weighted unit vertex normals of meshes (B, V, 3)
    (:func:`~hrr_garment.body.pseudo_normals.pseudo_normals`; a degenerate face's count as zero)."""
    tri = vertices[:, faces]  # (B, F, 3, 3)
    n = cross(tri[..., 1, :] - tri[..., 0, :], tri[..., 2, :] - tri[..., 0, :])
    unit = n / torch.clamp(torch.linalg.vector_norm(n, dim=-1, keepdim=True), min=1e-30)
    out = torch.zeros_like(vertices.transpose(0, 1))  # (V, B, 3)
    for k in range(3):
        u = tri[..., (k + 1) % 3, :] - tri[..., k, :]
        w = tri[..., (k + 2) % 3, :] - tri[..., k, :]
        angle = _angle(torch.linalg.vector_norm(cross(u, w), dim=-1), (u * w).sum(-1))  # (B, F)
        out = out.index_add(0, faces[:, k], (angle[..., None] * unit).transpose(0, 1))
    length = torch.linalg.vector_norm(out, dim=-1, keepdim=True)
    return unit, (out / torch.clamp(length, min=1e-12)).transpose(0, 1)


def _angle(sine: torch.Tensor, cosine: torch.Tensor) -> torch.Tensor:
    """atan2: exported in float32 whatever the graph's type (onnxruntime has no double Atan; an
    angle only weighs a vertex's normal, which only chooses a side)."""
    if torch.compiler.is_compiling() and sine.dtype != torch.float32:
        return torch.atan2(sine.float(), cosine.float()).to(sine.dtype)
    return torch.atan2(sine, cosine)
