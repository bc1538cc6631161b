"""The streaming step of a trained model as one PyTorch module that ONNX can hold
(:mod:`.onnx_model` exports it): a frame of poses in, the garment's world vertices out, each
character's window state as explicit inputs and outputs. The regression path of
:class:`~hrr_garment.inference.stream.CrowdStream`, stage by stage with the same formulas:

1. poses: local quaternions -> matrices, forward kinematics on the body's skeleton (its bone
   lengths, its pelvis height), as :meth:`~hrr_garment.inference.bodies.CharacterBody.play`;
2. features: the frame against the character's last one (:func:`~hrr_garment.motion.features.pair_features_batch`),
   its motion memory one frame on (:class:`~hrr_garment.motion.memory.MotionMemory`), the body's
   measures, the window of the last W frames;
3. the window step (:class:`~hrr_garment.models.codes.WindowCodes`): motion encoder, code
   entropy and classes, the code-space decoder's latents of the window's last frame;
4. the mesh decoder, the garment's rest offset on the body, the body frame to the world
   (:func:`~hrr_garment.motion.frame.from_body_frame`);
5. the collision push-out against the body's capsules and its strain limit
   (:mod:`hrr_garment.inference.collision`): the push's round and projections under conditionals
   (ONNX ``If``, skipped when nothing is inside), the strain limit's passes as a loop (ONNX
   ``Loop``) while a character still has an over-long edge, each character stopping on its own, as
   the package stops each frame.

A character's first frame is told by ``started`` = 0: its last pose is taken to be this one (zero
velocities), its memory starts at rest and its window is this frame repeated, as a stream starts.
In float32 throughout (the Python stream's FK and memory run in float64): within a few hundredths
of a millimetre of it over a real clip (tests/export/test_onnx.py).
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn
from torch._higher_order_ops.while_loop import while_loop

from ..inference.collision import LIMIT_TOLERANCE_M, OVER_RELAXATION, PushOutSettings
from ..models.codes import WindowCodes
from ..motion.features import SLICE_T, SLICE_V, SLICE_W
from ..motion.memory import MEMORY_WIDTH, VECTORS, MotionMemory
from ..motion.rotations import matrix_to_axis_angle, quat_to_matrix
from ..motion.skeleton import FEATURE_JOINTS, REST_PELVIS_HEIGHT, forward_kinematics


def _constant(module: nn.Module, name: str, value, dtype=torch.float32) -> None:
    module.register_buffer(name, torch.as_tensor(np.asarray(value), dtype=dtype), persistent=False)


def _yaw(rotation: torch.Tensor) -> torch.Tensor:
    """(N,) heading about +Y of (N, 3, 3) rotations (:func:`~hrr_garment.motion.rotations.yaw_of`)."""
    return torch.atan2(rotation[:, 0, 2], rotation[:, 2, 2])


def _turn_y(points: torch.Tensor, cos: torch.Tensor, sin: torch.Tensor) -> torch.Tensor:
    """(N, ..., 3) points turned about +Y by angles given as (N,) cosines and sines."""
    shape = (-1,) + (1,) * (points.dim() - 2)
    c, s = cos.reshape(shape), sin.reshape(shape)
    x, y, z = points[..., 0], points[..., 1], points[..., 2]
    return torch.stack([c * x + s * z, y, c * z - s * x], -1)


class PoseStage(nn.Module):
    """Local quaternions (N, 22, 4), x y z w, and pelvis positions (N, 3) -> global rotations
    (N, 22, 3, 3) and joint positions (N, 22, 3) on the body's skeleton."""

    def __init__(self, offsets: np.ndarray, parents: tuple[int, ...], pelvis_height: float):
        super().__init__()
        _constant(self, "offsets", offsets)
        self.parents, self.root_scale = tuple(parents), float(pelvis_height) / REST_PELVIS_HEIGHT

    def forward(self, rotations: torch.Tensor, root: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        local = quat_to_matrix(rotations[..., [3, 0, 1, 2]])
        return forward_kinematics(local, root * self.root_scale, self.offsets, parents=self.parents)


class FeatureStage(nn.Module):
    """A frame's features (N, F) against each character's last pose, its motion memory carried one
    frame on, and the body's measures: what :meth:`CrowdStream._step_frame` appends to a window."""

    def __init__(self, memory: MotionMemory | None, fps: float, body_vector: np.ndarray | None):
        super().__init__()
        self.fps, self.joints = float(fps), list(FEATURE_JOINTS)
        self.averages = 0 if memory is None else len(memory.spec.seconds)
        self.rows = 0 if memory is None else memory.spec.rows
        if memory is not None:
            _constant(self, "decay", memory.decay)  # (k, 1)
            _constant(self, "resonator_a", memory.resonator_a)  # (r, 2, 2)
            _constant(self, "resonator_b", memory.resonator_b)  # (r, 2)
            _constant(self, "omega", memory.omega)  # (r,)
        self.has_body = body_vector is not None
        if self.has_body:
            _constant(self, "body_vector", body_vector)

    def pair(self, previous: tuple[torch.Tensor, torch.Tensor], current: tuple[torch.Tensor, torch.Tensor]) -> torch.Tensor:
        """(N, 124) features of the current frame given the previous one (global rotations, positions)."""
        (rot0, pos0), (rot1, pos1) = previous, current
        n = rot1.shape[0]
        yaw0, yaw1 = _yaw(rot0[:, 0]), _yaw(rot1[:, 0])
        c, s = torch.cos(yaw1), torch.sin(yaw1)
        heading_t = torch.stack([torch.stack([c, torch.zeros_like(c), -s], -1),
                                 torch.stack([torch.zeros_like(c), torch.ones_like(c), torch.zeros_like(c)], -1),
                                 torch.stack([s, torch.zeros_like(c), c], -1)], -2)  # world -> body frame
        r = matrix_to_axis_angle(heading_t[:, None] @ rot1[:, self.joints]).reshape(n, -1)
        v = _turn_y((pos1[:, self.joints] - pos0[:, self.joints]) * self.fps, c, -s).reshape(n, -1)
        t = _turn_y((pos1[:, 0] - pos0[:, 0]) * self.fps, c, -s)
        step = yaw1 - yaw0
        w = torch.atan2(torch.sin(step), torch.cos(step))[:, None] * self.fps
        return torch.cat([r, v, t, w], 1)

    def memory(self, state: torch.Tensor, features: torch.Tensor, started: torch.Tensor) -> torch.Tensor:
        """The memory state (N, rows, 64) one frame on (at its start where ``started`` is 0)."""
        n = features.shape[0]
        u = torch.cat([features[:, SLICE_V], features[:, SLICE_T], features[:, SLICE_W]], 1)[:, None]  # (N, 1, 64)
        # at a start (MotionMemory.start): every average at the first velocities, every bob at rest
        # (x 0, q the first velocities)
        bob = torch.stack([torch.zeros_like(u[:, 0]), u[:, 0]], 1)  # (N, 2, 64)
        fresh = torch.cat([u.expand(n, self.averages, MEMORY_WIDTH), bob.repeat(1, (self.rows - self.averages) // 2, 1)], 1)
        # the last body frame's vectors seen from this one: turned by minus this frame's yaw step
        angle = -features[:, SLICE_W][:, 0] / self.fps
        c, s = torch.cos(angle), torch.sin(angle)
        vectors = state[..., :-1].reshape(n, self.rows, VECTORS, 3)
        x, y, z = vectors[..., 0], vectors[..., 1], vectors[..., 2]
        c4, s4 = c[:, None, None], s[:, None, None]
        turned = torch.stack([c4 * x + s4 * z, y, c4 * z - s4 * x], -1)
        carried = torch.cat([turned.reshape(n, self.rows, -1), state[..., -1:]], -1)
        averages = self.decay * carried[:, :self.averages] + (1.0 - self.decay) * u
        bobs = carried[:, self.averages:].reshape(n, -1, 2, MEMORY_WIDTH)
        bobs = self.resonator_a @ bobs + self.resonator_b[..., None] * u[:, None]
        stepped = torch.cat([averages, bobs.reshape(n, -1, MEMORY_WIDTH)], 1)
        return torch.where(started.reshape(-1, 1, 1) > 0, stepped, fresh)

    def memory_values(self, state: torch.Tensor) -> torch.Tensor:
        """(N, rows x 64): the averages, each resonator's w x and q (:meth:`MotionMemory.values`)."""
        n = state.shape[0]
        bobs = state[:, self.averages:].reshape(n, -1, 2, MEMORY_WIDTH)
        scaled = torch.stack([bobs[:, :, 0] * self.omega[None, :, None], bobs[:, :, 1]], 2)
        return torch.cat([state[:, :self.averages], scaled.reshape(n, -1, MEMORY_WIDTH)], 1).reshape(n, -1)

    def forward(self, previous, current, memory: torch.Tensor, started: torch.Tensor):
        """-> the frame's full features (N, F) and the next memory state."""
        features = self.pair(previous, current)
        parts = [features]
        if self.rows:
            memory = self.memory(memory, features, started)
            parts.append(self.memory_values(memory))
        if self.has_body:
            parts.append(self.body_vector.expand(features.shape[0], -1))
        return torch.cat(parts, 1), memory


class PushOutStage(nn.Module):
    """World vertices (N, V, 3) pushed out of the body's capsules posed by FK, then their edges
    stretched by the push limited (:func:`~hrr_garment.inference.collision.push_out` with
    :func:`~hrr_garment.inference.collision.limit_push_strain`)."""

    def __init__(self, capsules, smoothing, *, limits, settings: PushOutSettings, strain_passes: int = 60):
        super().__init__()
        joints, a, b, radii = capsules
        self.joints = [int(j) for j in joints]
        _constant(self, "cap_a", a)
        _constant(self, "cap_b", b)
        _constant(self, "radii", radii)
        self.settings, self.strain_passes = settings, int(strain_passes)
        # the smoothing's row-normalised adjacency as (row, column, weight) triplets: a gather, a
        # product and a scatter-add (ONNX has no sparse product)
        smoothing = smoothing.tocoo()
        _constant(self, "smooth_rows", smoothing.row, torch.int64)
        _constant(self, "smooth_cols", smoothing.col, torch.int64)
        _constant(self, "smooth_weights", smoothing.data[:, None])  # (nnz, 1): over the characters
        # a pass moves a vertex by the sum of its edges' half excesses (+ at an edge's first end, - at
        # its second), over-relaxed over its degree: the half and the weight folded into one factor
        _constant(self, "vertex_weight", (0.5 * OVER_RELAXATION / limits.degree)[:, None])
        _constant(self, "edges", limits.edges, torch.int64)
        _constant(self, "allowed", settings.max_strain * limits.rest_length)

    def distance(self, p: torch.Tensor, a: torch.Tensor, b: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Signed distances (N, V) to the union of capsules and the nearest one's outward normals.
        Through products of (N, V, 3) by (N, 3, C) (no (N, V, C, 3) temporaries, which cost most of
        a step in onnxruntime); ``p``, ``a``, ``b`` relative to the pelvis keep them to metres."""
        ab = b - a  # (N, C, 3)
        ab_ab = (ab * ab).sum(-1)[:, None]  # (N, 1, C)
        rel_ab = p @ ab.transpose(1, 2) - (a * ab).sum(-1)[:, None]  # (p - a) . ab: (N, V, C)
        rel_rel = (p * p).sum(-1, keepdim=True) - 2.0 * (p @ a.transpose(1, 2)) + (a * a).sum(-1)[:, None]
        s = torch.clamp(rel_ab / torch.clamp(ab_ab, min=1e-12), 0.0, 1.0)
        axis2 = rel_rel - s * (2.0 * rel_ab - s * ab_ab)  # |p - a - s ab|^2
        d, nearest = (torch.sqrt(torch.clamp(axis2, min=0.0)) - self.radii).min(-1)
        pick = torch.nn.functional.one_hot(nearest, a.shape[1]).to(p.dtype)  # (N, V, C)
        s_near = (pick * s).sum(-1, keepdim=True)
        diff = p - pick @ a - s_near * (pick @ ab)
        return d, diff / torch.clamp(torch.sqrt((diff * diff).sum(-1, keepdim=True)), min=1e-12)

    def smooth(self, disp: torch.Tensor) -> torch.Tensor:
        """One pass of the mean over each vertex's neighbours, vertex-major (V, N, 3) (see :meth:`limit`)."""
        terms = torch.index_select(disp, 0, self.smooth_cols) * self.smooth_weights[..., None]
        return torch.zeros_like(disp).index_add(0, self.smooth_rows, terms)

    def push(self, p: torch.Tensor, a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
        d, n = self.distance(p, a, b)
        for _ in range(self.settings.rounds):
            p, d, n = torch.cond((d < self.settings.margin).any(), self._round, _as_is, (p, d, n, a, b))
        for _ in range(4):  # exact projection, again where a push landed in another capsule
            p, d, n = torch.cond((d < 0).any(), self._project, _as_is, (p, d, n, a, b))
        return p

    def _round(self, p, d, n, a, b):
        """A push along the normals, spread to the neighbours, never below what is needed."""
        need = torch.clamp(self.settings.margin - d, min=0.0).transpose(0, 1)  # vertex-major, as smooth takes it
        normals = n.transpose(0, 1)
        hit = need > 0
        disp = need[..., None] * normals
        for _ in range(self.settings.smooth):
            disp = self.smooth(disp)
            short = torch.where(hit, torch.clamp(need - (disp * normals).sum(-1), min=0.0), torch.zeros_like(need))
            disp = disp + short[..., None] * normals
        p = p + disp.transpose(0, 1)
        return (p, *self.distance(p, a, b))

    def _project(self, p, d, n, a, b):
        p = p + torch.where(d < 0, self.settings.margin - d, torch.zeros_like(d))[..., None] * n
        return (p, *self.distance(p, a, b))

    def _edge_vectors(self, p: torch.Tensor) -> torch.Tensor:
        """(E, N, 3) of vertex-major points (V, N, 3)."""
        return torch.index_select(p, 0, self.edges[:, 1]) - torch.index_select(p, 0, self.edges[:, 0])

    def limit(self, pushed: torch.Tensor, unpushed: torch.Tensor) -> torch.Tensor:
        """Undo what of the push tears the cloth, on the characters with an edge over its limit.
        Vertex-major, (V, N, 3): gathers and scatter-adds of whole rows (along the characters' axis
        each exported with transposes that cost more than the arithmetic)."""
        pushed, unpushed = pushed.transpose(0, 1), unpushed.transpose(0, 1)
        before = torch.sqrt((self._edge_vectors(unpushed) ** 2).sum(-1))
        limit = torch.maximum(self.allowed[:, None], before)  # (E, N)
        length = torch.sqrt((self._edge_vectors(pushed) ** 2).sum(-1))
        torn = (length > limit * (1.0 + 1e-6)).any(0)
        passes = torch.zeros((), dtype=torch.int64)
        _, p, _, _ = while_loop(self._limiting, self._pass, (passes, pushed, limit, torn))  # an ONNX Loop
        return p.transpose(0, 1)

    def _limiting(self, passes: torch.Tensor, p: torch.Tensor, limit: torch.Tensor, active: torch.Tensor) -> torch.Tensor:
        return (passes < self.strain_passes) & active.any()

    def _pass(self, passes: torch.Tensor, p: torch.Tensor, limit: torch.Tensor, active: torch.Tensor):
        """One Jacobi pass of edge-length projection over every edge of the characters still over a limit."""
        d = self._edge_vectors(p)
        length = torch.sqrt((d * d).sum(-1))
        excess = torch.clamp(length - limit, min=0.0)
        active = active & (excess.max(0).values > LIMIT_TOLERANCE_M)  # a character stops on its own
        corr = (excess / torch.clamp(length, min=1e-12) * active.to(length.dtype))[..., None] * d  # (E, N, 3)
        gathered = torch.zeros_like(p).index_add(0, self.edges[:, 0], corr).index_add(0, self.edges[:, 1], -corr)
        return passes + 1, p + gathered * self.vertex_weight[..., None], limit.clone(), active

    def forward(self, vertices: torch.Tensor, rotations: torch.Tensor, positions: torch.Tensor) -> torch.Tensor:
        rot, pos = rotations[:, self.joints], positions[:, self.joints]
        centre = positions[:, :1]  # (N, 1, 3): the pelvis
        a = pos - centre + (rot @ self.cap_a[..., None])[..., 0]
        b = pos - centre + (rot @ self.cap_b[..., None])[..., 0]
        return self.limit(self.push(vertices - centre, a, b) + centre, vertices)


def _as_is(p: torch.Tensor, d: torch.Tensor, n: torch.Tensor, a: torch.Tensor, b: torch.Tensor):
    """The branch of a push step with nothing to move (a conditional's outputs may not alias its inputs)."""
    return p.clone(), d.clone(), n.clone()


class StreamStep(nn.Module):
    """One frame of N characters through the regression path; see the module docstring.

    Inputs: ``rotations`` (N, 22, 4) local quaternions x y z w, ``root`` (N, 3) pelvis positions
    (metres, Y up), and the state: ``started`` (N,) 0 at a character's first frame else 1,
    ``previous_rotations`` (N, 22, 3, 3), ``previous_positions`` (N, 22, 3), ``memory`` (N, rows, 64),
    ``window`` (N, W - 1, F). Outputs: ``vertices`` (N, V, 3), ``entropy`` (N,), ``codes`` (N, G), and
    the next state in the same order (``started`` all ones)."""

    def __init__(self, bundle, decoder, *, character, memory: MotionMemory | None, fps: float,
                 push_out: PushOutStage | None):
        super().__init__()
        record = character.record
        self.pose = PoseStage(record.skeleton.offsets, record.skeleton.parents, record.pelvis_height)
        measures = character.vector if bundle.codespace.config.body_features else None
        self.features = FeatureStage(memory, fps, measures)
        self.codes = WindowCodes(bundle.codespace.eval(), regression=True, last_frame=True)
        _constant(self, "motion_mean", bundle.motion_stats.mean)
        _constant(self, "motion_std", bundle.motion_stats.std)
        _constant(self, "latent_mean", bundle.latent_stats.mean)
        _constant(self, "latent_std", bundle.latent_stats.std)
        _constant(self, "garment_offset", character.offset)
        self.decoder, self.push_out = decoder, push_out
        self.latent_shape = tuple(bundle.codespace.latent_shape)

    def forward(self, rotations, root, started, previous_rotations, previous_positions, memory, window):
        rot, pos = self.pose(rotations, root)
        first = started.reshape(-1, 1, 1) <= 0
        previous = (torch.where(first[..., None], rot, previous_rotations), torch.where(first, pos, previous_positions))
        features, memory = self.features(previous, (rot, pos), memory, started)
        past = torch.where(first, features[:, None].expand_as(window), window)
        frames = torch.cat([past, features[:, None]], 1)  # (N, W, F)
        entropy, codes, latents = self.codes((frames - self.motion_mean) / self.motion_std)
        n = latents.shape[0]
        latents = (latents.reshape(n, -1) * self.latent_std + self.latent_mean).reshape(n, *self.latent_shape)
        local = self.decoder(latents) + self.garment_offset
        yaw = _yaw(rot[:, 0])
        origin = root * self.pose.root_scale - torch.tensor([0.0, REST_PELVIS_HEIGHT, 0.0])
        world = _turn_y(local, torch.cos(yaw), torch.sin(yaw)) + origin[:, None]
        if self.push_out is not None:
            world = self.push_out(world, rot, pos)
        return (world, entropy, codes, torch.ones_like(started), rot, pos, memory, frames[:, 1:])


def torch_decoder(fast_decoder) -> nn.Module:
    """The mesh decoder's PyTorch blocks (gathers and batched matmuls, the folded kernels of a
    :class:`~hrr_garment.models.fast_decoder.FastDecoder`) as a module to export."""

    class Decoder(nn.Module):
        def __init__(self):
            super().__init__()
            self.fast = fast_decoder

        def forward(self, latents: torch.Tensor) -> torch.Tensor:
            return self.fast._torch_forward(latents)

    return Decoder()

