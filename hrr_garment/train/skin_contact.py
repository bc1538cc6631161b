"""The contact phase's body where a body has a skin: the signed distance of decoded vertices to the
mesh the viewer sees, differentiable, for :mod:`.contact`.

The distance is the inverse-skinning collider's (:mod:`hrr_garment.body.skin_collider`), in its C
kernel (:mod:`hrr_garment.native.skin`; the numpy reference where no compiler is found), frame by
frame in threads (``torch.get_num_threads()``: the kernel is one thread a call and leaves Python's
lock). Its gradient is the outward normal the collider returns with it (the signed distance's
gradient wherever one point of the skin is nearest), so the backward pass costs nothing more.

Decoded frames are in the body frame (:mod:`hrr_garment.motion.frame`), and the collider is posed
there too: the body frame is a rigid move of the world (a turn about Y and a shift), and skinning
and its inverse commute with one rigid move of every joint, so the joints' rotations and positions
taken into the body frame pose the skin in it (tested equal to posing in the world).

Points far from the skin are not queried: each body's capsules grown to hold its posed skin
(:mod:`hrr_garment.body.skin_envelope`) give a lower bound on the distance to it, and a point whose
bound exceeds the caller's ``reach_m`` (the contact margin: the loss ``relu(margin - d)`` is zero
there, and so is its gradient) gets the bound instead, with a zero gradient. The bound also corrects
the collider where it calls a point inside that lies outside the grown capsules (so outside the
skin): the collider's side can be wrong far from the skin, beyond its grid (docs/bodies.md).
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np
import torch

from ..body.capsules import BodyModel, capsule_signed_distance
from ..body.skin_collider_store import stored_skin_collider
from ..body.skin_envelope import SkinEnvelope
from ..body.skinned_body import SkinnedBody
from ..motion.frame import body_heading, to_body_frame
from ..motion.motion import Motion
from ..native import default_threads, load_kernel
from ..native.capsules import capsule_sdf
from ..native.skin import SkinKernel

Query = Callable[[np.ndarray, np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]
_QUERIES: dict[int, tuple[SkinnedBody, Query]] = {}  # by the skin's id (held, so the id stays its)


def skin_query(skin: SkinnedBody) -> Query:
    """The collider's query of ``skin`` (points, rotations, positions -> distance, normal), in the C
    kernel where it compiles; built once a skin and kept in the workspace
    (:func:`~hrr_garment.body.skin_collider_store.stored_skin_collider`: a few seconds for an anny body)."""
    if id(skin) not in _QUERIES:
        collider = stored_skin_collider(skin)
        lib = load_kernel()
        _QUERIES[id(skin)] = (skin, collider.query if lib is None else SkinKernel(collider, lib).query)
        while len(_QUERIES) > 16:  # a dataset's few bodies
            del _QUERIES[next(iter(_QUERIES))]
    return _QUERIES[id(skin)][1]


def body_frame_pose(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """(T, J, 3, 3) global rotations and (T, J, 3) positions of the joints in the body frame."""
    _, heading = body_heading(motion)  # body frame -> world
    return np.einsum("tba,tjbc->tjac", heading, motion.global_rotations), to_body_frame(
        motion.joint_positions, motion
    )


class _SignedDistance(torch.autograd.Function):
    """Points (..., 3) -> the signed distance ``answer`` gives (numpy: points -> distances and their
    gradients); backward: the incoming gradient times that gradient."""

    @staticmethod
    def forward(ctx, points: torch.Tensor, answer: Callable) -> torch.Tensor:
        distance, gradient = answer(points.detach().numpy().astype(np.float64))
        ctx.save_for_backward(torch.from_numpy(gradient).to(points.dtype))
        return torch.from_numpy(distance).to(points.dtype)

    @staticmethod
    def backward(ctx, grad: torch.Tensor):
        (gradient,) = ctx.saved_tensors
        return grad[..., None] * gradient, None


def signed_distance(points: torch.Tensor, answer: Callable) -> torch.Tensor:
    """The distance ``answer`` gives ``points``, differentiable (:class:`_SignedDistance`)."""
    return _SignedDistance.apply(points, answer)


@dataclass(frozen=True)
class VisibleContacts:
    """Per stored frame, the joints posed in the body frame; per body (rows as :class:`.contact.
    BodyContacts`' ``radii``), its skin's query and envelope, or None for a body drawn as its capsules."""

    rotations: np.ndarray  # (frames, J, 3, 3) float32
    positions: np.ndarray  # (frames, J, 3) float32
    body: np.ndarray  # (frames,) int64 each frame's body row
    queries: tuple[Query | None, ...]
    envelopes: tuple[SkinEnvelope | None, ...]
    # per body row, its frames' grown capsules as :meth:`grown` made them (a frame's pose never
    # changes: made on its first batch and kept)
    _grown: dict[int, "_GrownCapsules"] = field(default_factory=dict, compare=False, repr=False)

    @classmethod
    def of(
        cls, motions: list[Motion], body: np.ndarray, skins: list[tuple[SkinnedBody | None, BodyModel]]
    ) -> "VisibleContacts":
        """Of the stored frames of ``motions`` (their frames in turn; ``body`` each frame's row)
        on the bodies ``skins`` (per row: the skin, or None, and the body's capsules)."""
        poses = [body_frame_pose(m) for m in motions]
        return cls(
            np.concatenate([r for r, _ in poses]).astype(np.float32),
            np.concatenate([p for _, p in poses]).astype(np.float32),
            np.asarray(body, np.int64),
            tuple(None if s is None else skin_query(s) for s, _ in skins),
            tuple(None if s is None else SkinEnvelope.of(s, capsules) for s, capsules in skins),
        )

    @property
    def skinned(self) -> list[bool]:
        """Per body row: whether it has a skin."""
        return [q is not None for q in self.queries]

    def grown(self, row: int, frames: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The capsules of body ``row`` grown to hold its skin posed as the stored ``frames`` (n,) of
        that body are (:meth:`~hrr_garment.body.skin_envelope.SkinEnvelope.grown`): ends (n, C, 3)
        twice and radii (n, C). Each frame's made on the first batch that holds it and kept (the
        same arrays, in float64): made every batch, they took a third of a contact phase."""
        if row not in self._grown:
            self._grown[row] = _GrownCapsules.empty(self.body == row, len(self.envelopes[row].body.radii))
        kept = self._grown[row]
        at = kept.slot[frames]
        new = np.unique(at[~kept.known[at]])
        if len(new):
            frame = kept.frames[new]
            rot, pos = self.rotations[frame].astype(np.float64), self.positions[frame].astype(np.float64)
            for held, made in zip(kept.capsules, self.envelopes[row].grown(rot, pos)):
                held[new] = made
            kept.known[new] = True
        return tuple(held[at] for held in kept.capsules)

    def distance(
        self, vertices: torch.Tensor, rows: torch.Tensor, *, fallback: torch.Tensor, reach_m: float
    ) -> torch.Tensor:
        """(n, V) signed distance of body-frame ``vertices`` (n, V, 3) of the stored frames ``rows``
        (n,) to their bodies' skins, ``fallback`` (n, V) for frames of bodies without one: the
        collider's wherever it is at most ``reach_m``, elsewhere a lower bound above it with a zero
        gradient (and the bound too where the collider answers less than a positive bound: there
        the point is outside the skin by at least the bound, the collider's side is wrong)."""
        rows_np = rows.numpy()
        body = self.body[rows_np]
        frames = np.flatnonzero([self.queries[b] is not None for b in body])
        if not len(frames):
            return fallback
        rot = self.rotations[rows_np[frames]].astype(np.float64)
        pos = self.positions[rows_np[frames]].astype(np.float64)
        grown = [None] * len(frames)  # each frame's capsules grown to hold its skin (none: ask every point)
        for row in np.unique(body[frames]) if np.isfinite(reach_m) else ():
            mine = np.flatnonzero(body[frames] == row)
            for k, capsules in zip(mine, zip(*self.grown(row, rows_np[frames[mine]]))):
                grown[k] = capsules

        def answer(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            distance, normal = np.full(points.shape[:2], -np.inf), np.zeros(points.shape)

            def one(k: int) -> None:
                if grown[k] is not None:
                    distance[k] = _capsule_distance(points[k], *grown[k])
                lower = distance[k].copy()
                near = np.flatnonzero(lower <= reach_m)
                if len(near):
                    query = self.queries[body[frames[k]]]
                    d, n = query(points[k, near], rot[k], pos[k])
                    # outside the grown capsules a point is outside the skin, at least that far: an
                    # answer nearer (the collider's side far from the skin) gives way to the bound
                    wrong = (lower[near] > 0.0) & (d < lower[near])
                    distance[k, near] = np.where(wrong, lower[near], d)
                    normal[k, near] = np.where(wrong[:, None], 0.0, n)

            with ThreadPoolExecutor(max(1, default_threads())) as pool:
                list(pool.map(one, range(len(frames))))
            return distance, normal

        picked = torch.from_numpy(frames)
        return fallback.index_copy(0, picked, signed_distance(vertices[picked], answer))


@dataclass(frozen=True)
class _GrownCapsules:
    """One body's frames' grown capsules (:meth:`VisibleContacts.grown`), those made so far."""

    frames: np.ndarray  # (n,) the body's stored frames
    slot: np.ndarray  # (all frames,) each of them at its place in ``frames`` (-1: another body's)
    known: np.ndarray  # (n,) bool, which are made
    capsules: tuple[np.ndarray, np.ndarray, np.ndarray]  # ends (n, C, 3) twice and radii (n, C)

    @classmethod
    def empty(cls, mine: np.ndarray, capsules: int) -> "_GrownCapsules":
        """None made yet, for the frames ``mine`` (all frames,) bool of a body of ``capsules``."""
        frames = np.flatnonzero(mine)
        slot = np.full(len(mine), -1)
        slot[frames] = np.arange(len(frames))
        n = len(frames)
        ends = (np.zeros((n, capsules, 3)), np.zeros((n, capsules, 3)))
        return cls(frames, slot, np.zeros(n, bool), (*ends, np.zeros((n, capsules))))


def _capsule_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """(N,) signed distance of points (N, 3) to one frame's capsules (C), on the calling thread: in
    the kernel where it compiles (a thread of the frames' pool; a team of its own costs more than the
    frame), else numpy."""
    lib = load_kernel()
    if lib is None:
        return capsule_signed_distance(points, a, b, radii=radii)[0]
    return capsule_sdf(lib, points[None], a[None], b=b[None], radii=radii, threads=1)[0][0]
