"""The body a garment is animated on: the model's own, a body file, a character, checked against
the bodies the model was trained on.

    body = animator.body("hero.json")            # body.json (hrr-body make / fit / nearest)
    body = animator.body("hero.glb")             # a skinned character, fitted as hrr-body fit does
    anim = animator.animate(motion, body=body)   # or body="hero.json" directly

A :class:`CharacterBody` holds what animating on it takes: the body (skeleton, pelvis height,
capsules for the push-out), its measures (:mod:`hrr_garment.body.measures`: what a model trained
across bodies reads with the motion), and the garment's rest offset on it
(:meth:`~hrr_garment.garment.dressing.DressedBody.offset`): models predict a garment relative to its
body at rest, and the offset stands it on this one. The garment is carried onto the body as the
simulator carried it (:func:`~hrr_garment.garment.dressing.dress`), so a body the model was trained
on gets the rest shape its training data had; on a skinned character it is kept clear of the
character's own mesh.

A body outside the range of the model's training bodies is refused with each measure that is out
(:class:`BodyOutsideRange`), or with ``allow_outside`` warned about: the garment then stands on
the body, but its motion is a guess from bodies unlike it.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..artifacts.bundle import Bundle
from ..body.body_file import BodyRecord, checked_record, read_body
from ..body.capsules import BodyModel, pose_ends
from ..body.mannequin import MANNEQUIN
from ..body.measures import body_vector
from ..body.retarget import played_by
from ..errors import InputError
from ..garment.dressing import DressedBody, dress
from ..motion.motion import Motion
from ..motion.skeleton import REST_PELVIS_HEIGHT
from .collision import PosedCapsules
from .edge_limits import EdgeLimits

if TYPE_CHECKING:
    from .visible_push import VisibleCollider

CHARACTER_SUFFIXES = (".glb", ".gltf")


class BodyOutsideRange(InputError):
    """A body unlike any the model was trained on."""


@dataclass(frozen=True)
class CharacterBody:
    """A body to animate on and the model's garment at rest on it."""

    dressed: DressedBody
    vector: np.ndarray  # (len(BODY_MEASURES),) its measures, metres
    offset: np.ndarray  # (V, 3) float32 the garment's rest offset on it (zero on the mannequin)
    # the push-out's strain limits made for it (push_limits), by the garment limits they came from: a
    # stream makes its crowd's bodies every step
    _push_limits: dict = field(default_factory=dict, compare=False, repr=False)

    @property
    def record(self) -> BodyRecord:
        return self.dressed.record

    @property
    def body(self) -> BodyModel:
        """The collision capsules on the body's skeleton (the push-out's and the previews')."""
        return self.dressed.body

    @property
    def name(self) -> str:
        return self.dressed.name

    def visible_collider(self) -> "VisibleCollider | None":
        """The mesh the viewer sees as the push-out measures it (built once a body in a process), or
        None where the body has none (the mannequin's is its capsules)."""
        from .visible_push import visible_collider

        skin = self.dressed.visible
        return None if skin is None else visible_collider(self.body, skin)

    def push_limits(self, limits: EdgeLimits, template: np.ndarray) -> EdgeLimits:
        """The push-out's strain limits (``limits``: the garment's, at rest as ``template`` (V, 3)) for
        the garment as it rests on this body: its own edge lengths; on the mannequin the template's."""
        if at_template_rest(self.offset):
            return limits
        key = id(limits)
        if key not in self._push_limits:  # the limits kept alive with their id
            self._push_limits[key] = (limits, limits.on_bodies(template + self.offset))
        return self._push_limits[key][1]

    def push_body(self, motion: Motion, visible: bool):
        """What the push-out takes for ``motion`` on this body: its visible mesh posed
        (:class:`~.visible_push.PosedSkin`) where ``visible`` and it has one, else its capsules."""
        collider = self.visible_collider() if visible else None
        if collider is None:
            return self.body
        from .visible_push import PosedSkin

        return PosedSkin.of(collider, motion)

    def play(self, motion: Motion) -> Motion:
        """``motion`` on this body: a clip on the canonical skeleton is played by the body (its bone
        lengths, its stride: :func:`~hrr_garment.body.retarget.played_by`); a clip already on the
        body's skeleton is kept; a clip on another body's skeleton is refused."""
        try:
            return played_by(motion, self.record)
        except ValueError as exc:
            raise InputError(motion.source or "motion", f"body {self.name!r}: {exc}") from None


def read_body_argument(body: str | Path) -> tuple[str, BodyRecord]:
    """A body file's name and record: body.json, or a skinned glTF / GLB character fitted as
    ``hrr-body fit`` fits it (its record carries its own skinned mesh, the body the viewer sees)."""
    path = Path(body)
    if path.suffix.lower() in CHARACTER_SUFFIXES:
        from ..body.character import character_body

        return path.stem, character_body(path)[0]
    return path.stem, read_body(path)


def character_body(
    bundle: Bundle,
    body: "CharacterBody | DressedBody | BodyRecord | str | Path | None" = None,
    *,
    allow_outside: bool = False,
    name: str | None = None,
) -> CharacterBody:
    """``body`` (None: the model's own, :attr:`~hrr_garment.artifacts.bundle.Bundle.default_body`)
    ready to animate ``bundle``'s garment on, checked against the model's training bodies. A
    dataset's body (:class:`~hrr_garment.garment.dressing.DressedBody`, a sequence record's ``dressed``)
    keeps its name."""
    if isinstance(body, CharacterBody):
        return body
    if isinstance(body, DressedBody):
        body, name = body.record, name or body.name
    if body is None:
        record = bundle.default_body
        label = name or (MANNEQUIN if bundle.manifest.default_body_is_mannequin else "the model's body")
    elif isinstance(body, BodyRecord):
        label = name or "body"
        record = checked_record(body, label)
    elif isinstance(body, (str, Path)):
        label, record = read_body_argument(body)
        label = name or label
    else:
        raise TypeError(
            f"body must be a body file's path, a BodyRecord or a CharacterBody, not {type(body).__name__}"
        )
    vector = body_vector(record)
    outside = bundle.body_range.outside(vector)
    if outside:
        where = body if isinstance(body, (str, Path)) else label
        count = bundle.body_range.bodies
        message = (
            f"body {label!r} is unlike the {count} bod{'y' if count == 1 else 'ies'} the model was trained "
            f"on: {'; '.join(outside)}"
        )
        if not allow_outside:
            raise BodyOutsideRange(
                where, message + " (train on bodies like it, or allow it and expect its motion to be a guess)"
            )
        warnings.warn(message + "; animating it anyway", stacklevel=2)
    dressed, _ = dress(label, record, bundle.template, made_for=bundle.made_for)
    return CharacterBody(dressed, vector, dressed.offset(bundle.template))


NEGLIGIBLE_OFFSET_M = 1e-9  # a rest offset no larger than this (a nanometre) stands the garment where it is


def at_template_rest(offset: np.ndarray) -> bool:
    """Whether a garment's rest ``offset`` on a body leaves it where the template rests (the mannequin)."""
    return bool(np.abs(offset).max(initial=0.0) <= NEGLIGIBLE_OFFSET_M)


@dataclass(frozen=True)
class CrowdBodies:
    """The bodies of a crowd push's characters (:class:`~.stream.CrowdStream`): one body for all, or arrays
    with a row per character."""

    vector: np.ndarray  # (b,) or (N, b) measures
    offset: np.ndarray  # (V, 3) or (N, V, 3) the garment's rest offsets
    body: object = None  # the one body's capsules (BodyModel), or None
    skeletons: np.ndarray | None = None  # (N, 22, 3) each character's skeleton offsets
    root_scale: np.ndarray | None = None  # (N,) each body's pelvis height over the mannequin's
    ends: tuple | None = None  # each character's capsules: joints (C,), local a and b (N, C, 3), radii (N, C)
    characters: tuple = ()  # the distinct bodies (CharacterBody) and which each character has
    which: np.ndarray | None = None  # (N,) int64, or None: every character the one body
    # the push-out's strain limits made for these bodies, by the garment limits they came from
    _push_limits: dict = field(default_factory=dict, compare=False, repr=False)

    @classmethod
    def of_one(cls, body) -> "CrowdBodies":
        return cls(body.vector, body.offset, body=body.body, characters=(body,))

    @classmethod
    def of_many(cls, bodies: list) -> "CrowdBodies":
        distinct = {id(b): b for b in bodies}  # by identity: a body's arrays make it unhashable
        each = [b.body.ends for b in bodies]
        joints = each[0][0]
        if any(not np.array_equal(e[0], joints) for e in each):
            raise ValueError(
                "the crowd's bodies have capsules on different joints; give every character one body kind"
            )
        ends = (
            joints,
            np.stack([e[1] for e in each]),
            np.stack([e[2] for e in each]),
            np.stack([b.body.radii for b in bodies]),
        )
        return cls(
            np.stack([b.vector for b in bodies]),
            np.stack([b.offset for b in bodies]),
            skeletons=np.stack([b.record.skeleton.offsets for b in bodies]),
            root_scale=np.array([b.record.pelvis_height / REST_PELVIS_HEIGHT for b in bodies]),
            ends=ends,
            characters=tuple(distinct.values()),
            which=np.array([list(distinct).index(id(b)) for b in bodies], np.int64),
        )

    def stand(self, local: np.ndarray) -> np.ndarray:
        """Body-frame garment vertices (N, V, 3) stood on these bodies: plus their rest offsets.
        On the mannequin the offset is zero but for rounding (1e-17 m, below float32's resolution
        at a garment's coordinates): nothing is added, which saves a 3 MB copy of a 64-character frame."""
        return local if at_template_rest(self.offset) else local + self.offset

    def push_limits(self, limits: EdgeLimits, template: np.ndarray) -> EdgeLimits:
        """:meth:`CharacterBody.push_limits` for the crowd's characters, a rest shape per distinct body
        (made once for the crowd's bodies)."""
        key = id(limits)
        if key not in self._push_limits:
            if self.which is None or len(self.characters) == 1:
                made = self.characters[0].push_limits(limits, template)
            elif all(at_template_rest(c.offset) for c in self.characters):
                made = limits
            else:
                made = limits.on_bodies(np.stack([template + c.offset for c in self.characters]), self.which)
            self._push_limits[key] = (limits, made)  # the limits kept alive with their id
        return self._push_limits[key][1]

    def push_body(self, poses: Motion, visible: bool):
        """What the push-out takes: with ``visible``, each character's visible mesh posed by its pose
        (:class:`~.visible_push.PosedSkin`) where every body of the crowd has one; else
        :meth:`capsules`."""
        colliders = [c.visible_collider() for c in self.characters] if visible else [None]
        if any(c is None for c in colliders):  # the mannequin among them: its capsules are its mesh
            return self.capsules(poses)
        from .visible_push import PosedSkin

        which = np.zeros(len(poses.global_rotations), np.int64) if self.which is None else self.which
        return PosedSkin.of_frames(tuple(colliders), which, poses)

    def capsules(self, poses: Motion):
        """What the push-out takes: the one body, or each character's capsules posed by its pose."""
        if self.body is not None:
            return self.body
        joints, a, b, radii = self.ends
        return PosedCapsules(
            *pose_ends(poses.global_rotations, poses.joint_positions, joints, a=a, b=b), radii
        )
