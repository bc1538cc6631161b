"""The torch step's first stages (:mod:`.torch_step`): a frame's poses through forward kinematics on
the body's skeleton (:class:`PoseStage`), and its features against each character's last pose with
the motion memory carried one frame on and the body's measures (:class:`FeatureStage`), as
:meth:`~hrr_garment.inference.stream.CrowdStream._step_frame` makes them."""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from ..motion.features import SLICE_T, SLICE_V, SLICE_W
from ..motion.memory import LONG_STILL_S, MEMORY_WIDTH, MOVING_ABOVE, STILL_BELOW, VECTORS, MotionMemory
from ..motion.rotations import matrix_to_axis_angle, quat_to_matrix, rotation_about_y, yaw_of
from ..motion.skeleton import FEATURE_JOINTS, REST_PELVIS_HEIGHT, forward_kinematics
from .torch_ops import constant, turn_y


def advanced_clock(
    clock: torch.Tensor, speed: torch.Tensor, still: torch.Tensor, *, fps: float
) -> torch.Tensor:
    """Stillness clock readings one frame on, given the frame's :meth:`FeatureStage.speed_and_still`
    (each (N, 1, 1), broadcast over ``clock``): reset over MOVING_ABOVE, the still share of a frame
    more otherwise, at most LONG_STILL_S (:func:`~hrr_garment.motion.memory.clock_step`)."""
    return torch.where(
        speed > MOVING_ABOVE, torch.zeros_like(clock), torch.clamp(clock + still / fps, max=LONG_STILL_S)
    )


class PoseStage(nn.Module):
    """Local quaternions (N, 22, 4), x y z w, and pelvis positions (N, 3) -> global rotations
    (N, 22, 3, 3) and joint positions (N, 22, 3) on the body's skeleton."""

    def __init__(self, offsets: np.ndarray, parents: tuple[int, ...], pelvis_height: float):
        super().__init__()
        constant(self, "offsets", offsets)
        self.parents, self.root_scale = tuple(parents), float(pelvis_height) / REST_PELVIS_HEIGHT

    def forward(self, rotations: torch.Tensor, root: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        local = quat_to_matrix(rotations[..., [3, 0, 1, 2]])
        return forward_kinematics(local, root * self.root_scale, self.offsets, parents=self.parents)


class FeatureStage(nn.Module):
    """A frame's features (N, F) against each character's last pose, its motion memory carried one
    frame on, and what conditions the model: the body's ``measures`` and the ``cloth``'s values (each
    None where the model reads none; the cloth's may come per character instead, :meth:`forward`):
    what :meth:`CrowdStream._step_frame` appends to a window."""

    def __init__(
        self, memory: MotionMemory | None, fps: float, measures: np.ndarray | None, cloth: np.ndarray | None
    ):
        super().__init__()
        self.fps, self.joints = float(fps), list(FEATURE_JOINTS)
        self.averages = 0 if memory is None else len(memory.spec.seconds)
        self.rows = 0 if memory is None else memory.spec.rows
        self.filter_rows = 0 if memory is None else memory.spec.filter_rows
        self.held = 0 if memory is None else len(memory.spec.held_seconds)
        self.clocked = memory is not None and bool(memory.spec.still_seconds)
        if self.clocked:
            constant(self, "still_seconds", np.array(memory.spec.still_seconds))
        if memory is not None:
            constant(self, "decay", memory.decay)  # (k, 1)
            constant(self, "resonator_a", memory.resonator_a)  # (r, 2, 2)
            constant(self, "resonator_b", memory.resonator_b)  # (r, 2)
            constant(self, "omega", memory.omega)  # (r,)
            constant(self, "held_rate", memory.held_rate)  # (h, 1)
        self.has_body, self.has_cloth = measures is not None, cloth is not None
        if self.has_body:
            constant(self, "body_vector", measures)
        if self.has_cloth:
            constant(self, "cloth", cloth)

    def pair(
        self, previous: tuple[torch.Tensor, torch.Tensor], current: tuple[torch.Tensor, torch.Tensor]
    ) -> torch.Tensor:
        """(N, 124) features of the current frame given the previous one (global rotations, positions)."""
        (rot0, pos0), (rot1, pos1) = previous, current
        n = rot1.shape[0]
        yaw0, yaw1 = yaw_of(rot0[:, 0]), yaw_of(rot1[:, 0])
        c, s = torch.cos(yaw1), torch.sin(yaw1)
        heading_t = rotation_about_y(yaw1).transpose(-1, -2)  # world -> body frame
        r = matrix_to_axis_angle(heading_t[:, None] @ rot1[:, self.joints]).reshape(n, -1)
        v = turn_y((pos1[:, self.joints] - pos0[:, self.joints]) * self.fps, c, -s).reshape(n, -1)
        t = turn_y((pos1[:, 0] - pos0[:, 0]) * self.fps, c, -s)
        step = yaw1 - yaw0
        w = torch.atan2(torch.sin(step), torch.cos(step))[:, None] * self.fps
        return torch.cat([r, v, t, w], 1)

    def memory(self, state: torch.Tensor, features: torch.Tensor, started: torch.Tensor) -> torch.Tensor:
        """The memory state (N, rows, 64) one frame on (at its start where ``started`` is 0)."""
        n = features.shape[0]
        u = torch.cat([features[:, SLICE_V], features[:, SLICE_T], features[:, SLICE_W]], 1)[
            :, None
        ]  # (N, 1, 64)
        # at a start (MotionMemory.start): every average (held or not) at the first velocities,
        # every bob at rest (x 0, q the first velocities)
        bob = torch.stack([torch.zeros_like(u[:, 0]), u[:, 0]], 1)  # (N, 2, 64)
        rows, held_from = self.filter_rows, self.filter_rows - self.held
        fresh = [
            u.expand(n, self.averages, MEMORY_WIDTH),
            bob.repeat(1, (held_from - self.averages) // 2, 1),
            u.expand(n, self.held, MEMORY_WIDTH),
        ]
        # the last body frame's vectors seen from this one: turned by minus this frame's yaw step
        angle = -features[:, SLICE_W][:, 0] / self.fps
        turned = turn_y(state[:, :rows, :-1].reshape(n, rows, VECTORS, 3), torch.cos(angle), torch.sin(angle))
        carried = torch.cat([turned.reshape(n, rows, 3 * VECTORS), state[:, :rows, -1:]], -1)
        averages = self.decay * carried[:, : self.averages] + (1.0 - self.decay) * u
        bobs = carried[:, self.averages : held_from].reshape(n, -1, 2, MEMORY_WIDTH)
        bobs = self.resonator_a @ bobs + self.resonator_b[..., None] * u[:, None]
        stepped = [averages, bobs.reshape(n, -1, MEMORY_WIDTH)]
        if self.held:  # motion.memory.moving_fraction: the averages stop while the body stands
            _, still = self.speed_and_still(features)
            hold = torch.exp(-(1.0 - still) * self.held_rate)  # (N, h, 1)
            stepped.append(hold * carried[:, held_from:] + (1.0 - hold) * u)
        if self.clocked:  # the stillness clock (motion.memory.clock_step), LONG_STILL_S at a start
            stepped.append(self.clock_step(state[:, rows:], features))
            fresh.append(torch.full_like(state[:, rows:], LONG_STILL_S))
        return torch.where(started.reshape(-1, 1, 1) > 0, torch.cat(stepped, 1), torch.cat(fresh, 1))

    def clock_step(self, clock: torch.Tensor, features: torch.Tensor) -> torch.Tensor:
        """The clock rows (N, 1, 64) one frame on: :func:`~hrr_garment.motion.memory.clock_step`."""
        return advanced_clock(clock, *self.speed_and_still(features), fps=self.fps)

    @staticmethod
    def speed_and_still(features: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(N, 1, 1) the feature joints' mean speed and how much of the frame counts as standing
        (motion.memory._still_ramp: the clock's count in frames, 1 less the held averages' moving)."""
        v = features[:, SLICE_V].reshape(features.shape[0], -1, 3)
        speed = torch.sqrt((v * v).sum(-1)).mean(-1)[:, None, None]
        return speed, torch.clamp((MOVING_ABOVE - speed) / (MOVING_ABOVE - STILL_BELOW), 0.0, 1.0)

    def memory_values(self, state: torch.Tensor) -> torch.Tensor:
        """(N, width): the averages, each resonator's w x and q, the held averages, the clock's
        (:meth:`MotionMemory.values`)."""
        n, held_from = state.shape[0], self.filter_rows - self.held
        bobs = state[:, self.averages : held_from].reshape(n, -1, 2, MEMORY_WIDTH)
        scaled = torch.stack([bobs[:, :, 0] * self.omega[None, :, None], bobs[:, :, 1]], 2)
        rows = [
            state[:, : self.averages],
            scaled.reshape(n, -1, MEMORY_WIDTH),
            state[:, held_from : self.filter_rows],
        ]
        parts = [torch.cat(rows, 1).reshape(n, -1)]
        if self.clocked:
            parts.append(torch.exp(-state[:, self.filter_rows, :1] / self.still_seconds[None]))
        return torch.cat(parts, 1)

    def forward(self, previous, current, memory: torch.Tensor, started: torch.Tensor, cloth=None):
        """-> the frame's full features (N, F) and the next memory state; ``cloth`` (N, m): each
        character's cloth values, for a model across cloths (None: the step's own cloth)."""
        features = self.pair(previous, current)
        parts = [features]
        if self.rows:
            memory = self.memory(memory, features, started)
            parts.append(self.memory_values(memory))
        n = features.shape[0]
        if self.has_body:
            parts.append(self.body_vector.expand(n, -1))
        if self.has_cloth:
            parts.append(self.cloth.expand(n, -1) if cloth is None else cloth)
        return torch.cat(parts, 1), memory
