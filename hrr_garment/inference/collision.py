"""Collision push-out: garment vertices found inside the posed body are moved just outside.

Per frame, every vertex within ``margin`` of the capsule body (or inside it) needs to move along
the nearest capsule's outward normal to ``margin`` outside. Moving only those vertices would leave
one-vertex spikes where a fold dips in; so the push is spread. Optionally its neighbours follow
first (``follow`` passes, off by default: docs/decisions/0023): a vertex within a few rings of a
pushed one moves with it, by the push less ``follow_slope`` times the rest length of the path
between them. The displacement field is smoothed over the mesh (``smooth`` Jacobi passes of the
uniform Laplacian, each keeping every vertex that must move at least at its move along its
direction). ``rounds`` such pushes, then up to four exact projections onto the surface (a push can
land in a neighbouring capsule, hence more than one). Last the strain limit undoes what of the push
tears the cloth (:mod:`.strain_limit`). With a C compiler the same steps run in the kernel of
:mod:`hrr_garment.native` (frames in parallel), which measures only the vertices near a capsule
and spreads only around the pushed ones (the same result: what it skips is exactly untouched);
this module's numpy version is the reference and the fallback. Before all of it, an option moves
the whole garment in its fast decoder's subspace (:mod:`.subspace_push`, docs/decisions/0032).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy.sparse import csr_matrix

from ..body.capsules import DEFAULT_BODY, BodyModel, frames_signed_distance
from ..garment.smoothing import mean_operator
from ..motion.frame import body_heading
from ..motion.motion import Motion
from ..sim.quality import PENETRATION_DEPTH_M
from .edge_limits import EdgeLimits
from .strain_limit import MAX_PUSH_STRAIN, limit_push_strain, native_strain_limit
from .take_back import take_back

if TYPE_CHECKING:
    from .subspace_push import SubspacePush
    from .visible_push import PosedSkin

STRETCH_SLACK = 0.1  # (PushOutSettings.stretch_slack)
RELEASE_PASSES = 2  # a torn frame pushed again at most this many times, letting go of more limbs
PROJECTIONS = 4  # exact projections at most after the rounds (the kernel's and the ONNX graph's too)


@dataclass
class PushOutReport:
    """How much of the garment was inside the body before and after the push-out."""

    inside_before: float  # mean over frames of the fraction of vertices more than `depth` inside
    inside_after: float
    worst_before: float  # worst frame
    worst_after: float
    # the share of frames on which the strain limit moved an edge: where the push alone tore the cloth
    # (issue 82's bar: at most 5 %); 0 without limits
    limited: float = 0.0


@dataclass(frozen=True)
class PushOutSettings:
    """How the push-out moves the cloth (the defaults are the product's)."""

    margin: float = 0.002  # metres outside the body surface a pushed vertex lands
    # rings around a pushed vertex that follow it (with EdgeLimits; 0: none): measured not to pay on
    # a trained model (docs/decisions/0023), so off
    follow: int = 0
    follow_slope: float = (
        0.25  # a follower moves the push less this x its rest distance from the pushed vertex
    )
    smooth: int = 4  # passes spreading each push to the neighbours (never below what is needed)
    rounds: int = 1  # push-and-spread rounds before the exact projection
    depth: float = PENETRATION_DEPTH_M  # metres inside the body that count as penetration in the report
    max_strain: float = MAX_PUSH_STRAIN  # no edge stretched past this x its rest length by the push ...
    # ... nor one the decoder stretched further by more than this x its rest length: the limit
    # repairs tears, not a push that lengthens an already long edge by a hair
    stretch_slack: float = STRETCH_SLACK
    chunk: int = 64  # frames processed at once
    # a frame the push tore pushed again without the limb capsules holding the torn cloth
    # (.limb_release; capsule bodies and the mesh push only). Off: on the real-quick model it halves
    # the frames the strain limit repairs (42.9 -> 21.3 %) but leaves 4 x the cloth inside the body
    # (0.14 -> 0.63 %) where the model put it through a limb (docs/decisions/0041)
    release_limbs: bool = False
    # the residual and detail modes' additions to the regression taken back first where they carry
    # the cloth into the body (.take_back; the frame path then decodes the regression too): on a
    # character's model the frames the limit repairs 45.9 -> 35.4 %, for 25 % more of a streamed
    # step (decision 0046)
    take_back: bool = True
    # the push in the garment's subspace before the mesh push (.subspace_push; None: none), made
    # per bundle (Animator.push_settings)
    subspace: "SubspacePush | None" = None

    @property
    def takes_back(self) -> bool:
        """Whether a push with these settings takes a mode's additions back first: asked, and no
        subspace push, which moves the cloth as it came better than it moves it taken back
        (decision 0046)."""
        return self.take_back and self.subspace is None


PUSH_OUT = PushOutSettings()


@dataclass(frozen=True)
class PosedCapsules:
    """Capsules posed already, frame by frame: what :func:`push_out` takes instead of a body when
    each frame is another character's body (a crowd's)."""

    a: np.ndarray  # (T, C, 3) end points
    b: np.ndarray  # (T, C, 3)
    radii: np.ndarray  # (T, C) each frame's radii, or (C,) shared


def push_out(  # noqa: PLR0913  (the cloth, its body and how to push: each its own)
    vertices: np.ndarray,
    motion: Motion,
    faces: np.ndarray,
    *,
    body: "BodyModel | PosedCapsules | PosedSkin" = DEFAULT_BODY,
    settings: PushOutSettings | None = None,
    mean: csr_matrix | None = None,
    limits: EdgeLimits | None = None,
    report: bool = True,
    base: np.ndarray | None = None,
) -> tuple[np.ndarray, PushOutReport | None]:
    """(T, V, 3) world vertices -> pushed copy and a report (fractions of vertices > ``depth`` inside).
    ``mean``: :func:`mean_operator` of the faces, when the caller keeps one (streaming). Frames are
    processed ``chunk`` at a time, all at once within a chunk. With ``limits`` (:class:`EdgeLimits`
    of the faces and the template's rest positions), the push stretches no edge past ``max_strain``
    times its rest length, or past its stretch before the push where that was more
    (:func:`~.strain_limit.limit_push_strain`). Without ``report`` (a stream, which discards it) the
    report is None, and the frames the limit moved are not measured again (a quarter of a crowd's
    push-out).
    ``body``: the body's capsules, posed by ``motion``, or :class:`PosedCapsules`, or the mesh the
    viewer sees (:class:`~.visible_push.PosedSkin`: the fractions are then of the vertices inside
    it). With ``settings.subspace`` (:class:`~.subspace_push.SubspacePush`) each frame is first
    moved in the garment's subspace (measured against the same body), and the limit measures the
    push against the moved frame; the report's "before" is the cloth as it came. With ``base``
    ((T, V, 3): the regression's cloth under a mode's additions) the additions are first taken back
    where they carry the cloth into the body (:mod:`.take_back`; not before a subspace push, which
    does better on the cloth as it came); "before" is still as it came."""
    settings = PUSH_OUT if settings is None else settings  # read here: the product's settings are one object
    rows = None if limits is None else limits.body_of_frame
    if rows is not None and len(rows) != len(vertices):
        raise ValueError(f"strain limits made for {len(rows)} frames' bodies, {len(vertices)} frames pushed")
    mean = mean_operator(faces, vertices.shape[1]) if mean is None else mean
    base = base if settings.takes_back else None
    pushed = _push(vertices, motion, faces, body, settings, mean, limits, report, base)
    out, before, after, torn, measure = pushed
    capsules = isinstance(body, (BodyModel, PosedCapsules))  # the visible mesh has none to let go of
    if (
        capsules
        and limits is not None
        and settings.release_limbs
        and settings.subspace is None
        and torn.any()
    ):
        torn, redone = _release_torn(out, vertices, torn, (motion, faces, body), settings, mean, limits)
        if report and redone.any():  # measured against the whole body, the limbs let go included
            rows = np.flatnonzero(redone)
            after[rows] = (measure(out[rows].astype(np.float64), rows)[0] < -settings.depth).mean(1)
    if not report:
        return out, None
    return out, PushOutReport(
        float(before.mean()),
        float(after.mean()),
        float(before.max(initial=0)),
        float(after.max(initial=0)),
        limited=float(torn.mean()) if limits is not None and len(torn) else 0.0,
    )


def _release_torn(out, unpushed, torn, clip, settings: PushOutSettings, mean, limits):
    """The frames ``torn`` pushed again (into ``out``) without the limb capsules that hold the torn
    cloth (:mod:`.limb_release`), twice at most; returns (T,) the frames the limit still moved and
    (T,) those pushed again."""
    from .limb_release import RELEASED_RADIUS, held_limbs, limb_capsules

    motion, faces, body = clip
    posed = body if isinstance(body, PosedCapsules) else PosedCapsules(*body.pose_motion(motion), body.radii)
    radii = np.array(np.broadcast_to(posed.radii, posed.a.shape[:2]))
    limbs = limb_capsules(body if isinstance(body, BodyModel) else None)
    again = dataclasses.replace(settings, release_limbs=False)
    unlimited = dataclasses.replace(again, max_strain=np.inf)
    redone = np.zeros(len(torn), bool)
    for _ in range(RELEASE_PASSES):
        rows = np.flatnonzero(torn)
        pushed = PosedCapsules(posed.a[rows], posed.b[rows], radii[rows])
        limited = limits.of_frames(rows)
        bare = _push(unpushed[rows], motion, faces, pushed, unlimited, mean, limited, False)[0]
        repaired = np.any(out[rows] != bare, axis=-1)  # (rows, V): the vertices the limit moved
        ends = (pushed.a, pushed.b, pushed.radii)
        let_go = held_limbs(repaired, unpushed[rows], ends=ends, margin=settings.margin, limbs=limbs)
        rows, let_go = rows[let_go.any(1)], let_go[let_go.any(1)]
        if not len(rows):
            break
        radii[rows] = np.where(let_go, RELEASED_RADIUS, radii[rows])
        pushed = PosedCapsules(posed.a[rows], posed.b[rows], radii[rows])
        out[rows], _, _, torn[rows], _ = _push(
            unpushed[rows], motion, faces, pushed, again, mean, limits.of_frames(rows), False
        )
        redone[rows] = True
    return torn, redone


def _limited(
    points, reference, limits: EdgeLimits, settings: PushOutSettings
) -> tuple[np.ndarray, np.ndarray]:
    """(T, V, 3) ``points`` strain-limited in place against ``reference`` (the push-out's limit), and
    (T,) the frames the limit moved."""
    return limit_push_strain(
        points, reference, limits, max_strain=settings.max_strain, in_place=True, slack=settings.stretch_slack
    )


def _inside(points, skin, measure, settings: PushOutSettings) -> np.ndarray:
    """(T,) each frame's share of ``points`` (T, V, 3) more than the report's depth inside the body
    (``measure``, :func:`_push`'s; ``skin``: the visible mesh's, where the body is one)."""
    points = np.asarray(points, np.float64)
    if skin is None:
        return (measure(points, slice(None))[0] < -settings.depth).mean(1)
    return skin.deeper_inside(points, settings.depth, settings.margin)


def _push(  # noqa: PLR0913  (push_out's arguments, passed on)
    vertices, motion, faces, body, settings: PushOutSettings, mean, limits, report, base=None
):
    """:func:`push_out`'s take-back (with ``base``), push and strain limit: the frames pushed, (T,)
    fractions inside before (of the frames as they came) and after, (T,) the frames the limit
    moved, and the measure of the frames against ``body``."""
    margin, smooth, rounds, depth, chunk = (
        settings.margin,
        settings.smooth,
        settings.rounds,
        settings.depth,
        settings.chunk,
    )
    from .visible_push import PosedSkin

    skin = body if isinstance(body, PosedSkin) else None
    if skin is not None:
        posed = skin.hulls
    else:
        posed = (
            body if isinstance(body, PosedCapsules) else PosedCapsules(*body.pose_motion(motion), body.radii)
        )
    a, b, radii = posed.a, posed.b, posed.radii
    framed = (lambda rows: radii[rows]) if np.ndim(radii) == 2 else (lambda rows: radii)  # noqa: E731

    def measure(points: np.ndarray, rows) -> tuple[np.ndarray, np.ndarray]:
        """Signed distances and normals of the frames ``rows`` (a slice or indices) of the push-out."""
        if skin is not None:
            return skin.distance(points, rows, margin)
        return frames_signed_distance(points, a[rows], b[rows], radii=framed(rows))

    before, after, torn = np.zeros(len(vertices)), np.zeros(len(vertices)), np.zeros(len(vertices), bool)
    from ..native import default_threads, load_kernel
    from ..native.body import PushSteps, push_out_frames

    lib = load_kernel()
    original, turn = vertices, None if settings.subspace is None else body_heading(motion)[1]
    if lib is not None:  # the same steps in C, frames in parallel: numpy's per-step overheads dominated.
        # Each frame taken into float64 as it comes, pushed, limited and converted back while it is in cache
        # (the limit measuring only the edges of the vertices the push moved): a 32-character crowd
        # spent a millisecond a frame converting and copying whole batches
        out = np.empty(vertices.shape, np.float32)
        torn = np.zeros(len(out), bool)
        steps = PushSteps(
            mean=mean,
            margin=margin,
            smooth=smooth,
            rounds=rounds,
            depth=depth,
            mesh=None if limits is None else limits.push_mesh(settings),
            limit=None
            if limits is None
            else native_strain_limit(limits, settings.max_strain, settings.stretch_slack),
            subspace=None if settings.subspace is None else settings.subspace.native,
        )
        skins = None if skin is None else skin.native(measure_after=report)
        for start in range(0, len(out), chunk):
            sl = slice(start, start + chunk)
            _, before[sl], after[sl], torn[sl] = push_out_frames(
                lib,
                vertices[sl],
                (a[sl], b[sl], framed(sl)),
                # the limit's rows (a rest per body) from this chunk's first frame
                steps=steps
                if steps.limit is None
                else steps._replace(limit=steps.limit._replace(first_frame=start)),
                turn=None if turn is None else turn[sl],
                skin=None if skins is None else skins.address(start),
                threads=default_threads(),
                out=out[sl],
                base=None if base is None else base[sl],
            )
    else:
        took = np.zeros(len(vertices), bool)
        if base is not None:  # the kernel's reference; the take-back limited against the cloth as it came
            vertices = take_back(vertices, base, posed if skin is None else skin, margin=margin, mean=mean)
            if limits is not None:
                vertices, took = _limited(vertices, original, limits, settings)
        if settings.subspace is not None:
            vertices = settings.subspace(vertices, motion, (a, b, radii) if skin is None else skin, margin)
        out = np.empty(vertices.shape, np.float32)
        for start in range(0, len(out), chunk):
            sl = slice(start, start + chunk)
            out[sl], before[sl], after[sl] = _push_frames(
                vertices[sl].astype(np.float64), lambda p, rows=sl: measure(p, rows), mean, settings, limits
            )
        if limits is not None:
            out, torn = _limited(out, vertices, limits, settings)
            torn |= took
    # "before": as it came, not after the subspace push or (in numpy: the kernel counts it) the take-back
    if report and (settings.subspace is not None or (base is not None and lib is None)):
        before = _inside(original, skin, measure, settings)
    # only the frames the limit moved have a new "after" (the kernel measures them against the skin itself)
    if limits is not None and report and torn.any() and (lib is None or skin is None):
        rows = np.flatnonzero(torn)
        after[rows] = (measure(out[rows].astype(np.float64), rows)[0] < -depth).mean(1)
    return out, before, after, torn, measure


def follow_pushes(
    need: np.ndarray, normal: np.ndarray, limits: EdgeLimits, passes: int, slope: float
) -> tuple[np.ndarray, np.ndarray]:
    """The neighbour-follow: (T, V) pushes and (T, V, 3) their directions -> the same with each
    vertex within ``passes`` rings of a pushed one moving at least as far as that push less
    ``slope`` times their rest distance along the path (a max-plus Jacobi pass per ring, in the
    ring table's order; a vertex takes the direction of the neighbour that sets its push, the
    first of equals). Vertices that need no push and follow none keep 0."""
    req = need.copy()
    direction = np.where((need > 0)[..., None], normal, 0.0)
    drop = slope * limits.ring_length  # (V, D)
    rows = np.arange(len(need))[:, None]
    for _ in range(passes):
        cand = req[:, limits.ring] - drop  # (T, V, D)
        j = cand.argmax(-1)
        best = np.take_along_axis(cand, j[..., None], -1)[..., 0]
        better = best > req
        if not better.any():
            break
        source = limits.ring[np.arange(need.shape[1])[None], j]  # (T, V): the neighbour that sets the push
        direction = np.where(better[..., None], direction[rows, source], direction)
        req = np.where(better, best, req)
    return req, direction


def _push_frames(
    p: np.ndarray,
    body,
    mean: csr_matrix,
    settings: PushOutSettings,
    limits: EdgeLimits | None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The reference (and the path without a C compiler): whole-mesh arrays, frames at once;
    ``body``: the frames' capsule ends a, b (T, C, 3) and the radii (C,), or a function of the
    frames' points (T, V, 3) giving their signed distances and normals; ``limits`` for the
    neighbour-follow (None: no follow)."""
    if callable(body):
        distance = body
    else:
        a, b, radii = body
        distance = lambda q: frames_signed_distance(q, a, b, radii=radii)  # noqa: E731
    margin, smooth, rounds, depth = settings.margin, settings.smooth, settings.rounds, settings.depth
    t, v = p.shape[:2]
    d, n = distance(p)
    before = (d < -depth).mean(1)
    for _ in range(rounds):
        need = np.maximum(margin - d, 0.0)  # how far along the normal each vertex must move
        if not need.any():
            break
        if limits is not None and settings.follow > 0:
            need, n = follow_pushes(need, n, limits, settings.follow, settings.follow_slope)
        hit = need > 0
        disp = need[..., None] * n
        for _ in range(smooth):  # spread the push to the neighbours, never below what is needed
            disp = (mean @ disp.transpose(1, 0, 2).reshape(v, -1)).reshape(v, t, 3).transpose(1, 0, 2)
            short = np.where(hit, np.maximum(need - (disp * n).sum(-1), 0.0), 0.0)
            disp += short[..., None] * n
        p = p + disp
        d, n = distance(p)
    for _ in range(PROJECTIONS):  # exact projection; repeated where a push lands in another capsule
        inside = d < 0
        if not inside.any():
            break
        p = p + np.where(inside, margin - d, 0.0)[..., None] * n
        d, n = distance(p)
    return p.astype(np.float32), before, (d < -depth).mean(1)
