"""A performer's carriage: how the pelvis, the chest and the collars are held, drawn per clip.

The kinds plan what a body does (steps, turns, swings) on an upright, square-shouldered body. Real
performers do it tilted: over 52 CMU clips (subjects 01-09 and the shared three, measured on the
canonical skeleton after reading) the pelvis is pitched forward 10.4 deg on average (clip means
sd 6.4), the chest leans back from it by 10.0 deg (sd 8.4) and turns within the clip (sd 8.8 deg
about the spine), and each collar is turned 13.8 deg (sd 3.0) from its rest. The kinds alone: a
pelvis tilt of 1.8 deg, the chest 1.0 deg forward of it, a turn of sd 2.9 deg, collars at rest. A
model trained on upright clips put the dress's bodice into the chest of such a performer: the
quick model decoded 7.4 % of the cloth more than 5 mm inside CMU 02_01's body where its own kinds
of clip had 0.1-0.3 % (docs/motion.md, *Procedural motions*).

So a clip of a preset with ``posture: drawn`` gets a :class:`Posture` drawn from the same generator
after the kind's own draws (a seed's steps and timing are the kind's; only the carriage is added):
a constant pelvis tilt and chest lean with a slow sway about them, a chest turn, and a rotation of
each collar, each drawn about the real clips' means and clipped to about their 5-95 % range.

Not drawn: the stride's twist. A real walker's pelvis turns about its heading with the leading leg
and the chest against it (:attr:`Carriage.pelvis_turn_sd` measures the first; the kinds' pelvis
never turns); drawn as well, it made the quick model worse on real clips, not better
(docs/decisions/0047-stride-twist-not-drawn.md).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import uniform_filter1d

from ..frame import body_heading
from ..rotations import matrix_to_axis_angle
from ..skeleton import JOINT_INDEX
from .plan import Plan

DEG = np.pi / 180.0
POSTURES = ("upright", "drawn")  # the names a preset's ``posture`` and synthesize() take


@dataclass(frozen=True)
class Posture:
    """How a clip's body is held (radians); the zero posture is the kinds' upright body."""

    pelvis_tilt: float = 0.0  # forward pitch of the pelvis added to the kind's
    chest_lean: float = 0.0  # forward lean of the chest from the pelvis added to the kind's (< 0: back)
    chest_turn: float = 0.0  # yaw of the chest from the pelvis added to the kind's
    sway: float = 0.0  # amplitude of a slow sway of the tilt and the lean about their values
    sway_hz: float = 0.2
    sway_phase: float = 0.0
    collars: dict[str, tuple[float, float, float]] = field(default_factory=dict)  # side -> rotation vector

    def carried(self, plan: Plan) -> Plan:
        """``plan`` with this posture added to its curves."""
        sway = self.sway * np.sin(2 * np.pi * self.sway_hz * plan.t + self.sway_phase)
        return dataclasses.replace(
            plan,
            pelvis_pitch=plan.curve(plan.pelvis_pitch) + self.pelvis_tilt + 0.5 * sway,
            spine_lean=plan.curve(plan.spine_lean) + self.chest_lean - 0.5 * sway,
            spine_twist=plan.curve(plan.spine_twist) + self.chest_turn,
            collar_rotation={side: np.asarray(v, np.float64) for side, v in self.collars.items()},
        )


UPRIGHT = Posture()


def _clipped_normal(rng: np.random.Generator, mean: float, sd: float, low: float, high: float) -> float:
    return float(np.clip(rng.normal(mean, sd), low, high))


def draw_posture(rng: np.random.Generator) -> Posture:
    """A performer's carriage about the real clips' (module docstring), in degrees below."""
    collars = {}
    for side, sign in (("l", 1.0), ("r", -1.0)):
        mean = (4.0, -4.0 * sign, 3.0 * sign)
        collars[side] = tuple(_clipped_normal(rng, m, 7.0, m - 14.0, m + 14.0) * DEG for m in mean)
    return Posture(
        pelvis_tilt=_clipped_normal(rng, 8.5, 5.0, -2.0, 20.0) * DEG,
        chest_lean=_clipped_normal(rng, -10.0, 7.0, -25.0, 6.0) * DEG,
        chest_turn=_clipped_normal(rng, 0.0, 4.0, -8.0, 8.0) * DEG,
        sway=float(rng.uniform(0.0, 8.0)) * DEG,
        sway_hz=float(rng.uniform(0.1, 0.5)),
        sway_phase=float(rng.uniform(0.0, 2 * np.pi)),
        collars=collars,
    )


@dataclass(frozen=True)
class Carriage:
    """How a clip holds its body, measured (degrees): what :func:`draw_posture` is drawn to match."""

    pelvis_pitch: float  # the pelvis's up axis towards its heading, mean over the clip
    chest_lean: float  # the chest's (spine3's) up axis towards the pelvis's forward, mean (< 0: back)
    chest_turn_sd: float  # the chest's yaw from the pelvis, its spread over the clip
    collar: float  # the collars' rotation from the chest, mean over both and the clip
    pelvis_turn_sd: float  # the pelvis's yaw from its heading over the second about each frame, its spread


def carriage(motion) -> Carriage:
    """``motion``'s :class:`Carriage` (any canonical clip: read, procedural or edited)."""
    glob = motion.global_rotations.astype(np.float64)
    pelvis = glob[:, JOINT_INDEX["pelvis"]]
    yaw, heading = body_heading(motion)  # the pelvis's yaw and its level frame
    forward = heading[:, :, 2]
    pitch = np.degrees(np.arcsin(np.clip((pelvis[:, :, 1] * forward).sum(1), -1.0, 1.0)))
    chest = np.einsum("tji,tjk->tik", pelvis, glob[:, JOINT_INDEX["spine3"]])  # in the pelvis's frame
    lean = np.degrees(np.arcsin(np.clip(chest[:, 2, 1], -1.0, 1.0)))
    turn = np.degrees(np.arctan2(-chest[:, 2, 0], chest[:, 0, 0]))
    collars = motion.local_rotations[:, [JOINT_INDEX["l_collar"], JOINT_INDEX["r_collar"]]]
    angle = np.degrees(np.linalg.norm(matrix_to_axis_angle(collars.astype(np.float64)), axis=-1))
    yaw = np.degrees(np.unwrap(yaw))
    wobble = yaw - uniform_filter1d(yaw, min(len(yaw), 31), mode="nearest")  # less the clip's own turns
    return Carriage(
        float(pitch.mean()), float(lean.mean()), float(turn.std()), float(angle.mean()), float(wobble.std())
    )
