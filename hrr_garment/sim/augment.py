"""Splices and clips played backward: new training motion made of the training clips (issue 50,
augmentation toward new contents).

A splice puts the upper body of one motion file (spine, head, arms) on the root and legs of
another of a different content, over a window of the preset's clip length, optionally with one arm
played late against the other (:mod:`hrr_garment.motion.compose`). Each is drawn from the
**training** clips only, once the split is known, so no held-out style or content reaches training
through a splice; splices always train. A drawn splice whose limbs pass through the body (a hand
through the hips where a bow's arms meet a run's legs: :mod:`hrr_garment.body.self_contact`) is
refused before it is simulated and another is drawn. The draw is seeded and depends only on the
training clips, so a re-run plans the same splices and finds them simulated.

``backward`` adds windows of training clips played backward
(:func:`~hrr_garment.motion.compose.played_backward`): a walk becomes a walk backward, a sit-down a
stand-up, contents a library of forward captures lacks. Their poses are the capture's own, so they
need no check for limbs through the body. They are drawn by a generator of their own, so adding them
leaves the splices' draw as it was.

``stops`` adds windows of training clips after which the body stops dead and stands
(:func:`~hrr_garment.motion.compose.held_still`): the cloth's swing dying away and the skirt coming
to rest, which clips cut from longer captures almost never show, and which a game shows every time
a character's animation ends in a still pose. They too have a generator of their own. No preset adds
them: 100 of them did not teach a model the truth's slow settling after a stop (issue 85;
docs/history/results-log.md, "Teaching a model to stop").
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..body.self_contact import self_intersecting_frames
from ..motion.motion import FPS
from .sources import DEFAULT_NAME_PATTERN, clip_group

if TYPE_CHECKING:  # the plan builds its options from a preset (sim.plan imports this module)
    from .plan import SequenceSpec

SPLICE_PREFIX = "splice_"
BACKWARD_PREFIX = "backward_"
STOP_PREFIX = "stopstand_"  # not "stop_": a game's own animations are often named so
# the sequences a build plans once the split is known
AUGMENT_PREFIXES = (SPLICE_PREFIX, BACKWARD_PREFIX, STOP_PREFIX)
DRAWS_PER_SPLICE = 20  # tries before the plan settles for fewer splices than asked


@dataclass(frozen=True)
class SpliceSettings:
    """How many splices a build adds and how they are drawn (a preset's ``splices:`` section)."""

    count: int = 0  # splices to add (0: none)
    seconds: float = 4.0  # each splice's length
    arm_delay_s: float = 0.0  # one arm up to this late against the other, drawn per splice (0: never)
    field: str = "content"  # the name field whose values must differ between legs and upper body
    backward: int = 0  # windows of training clips (``seconds`` long) played backward to add (0: none)
    stops: int = 0  # windows of training clips that stop dead, then stand, to add (0: none)
    stop_motion_s: float = 3.0  # each stop's motion before it stops
    stop_hold_s: float = 6.0  # and how long the body then stands
    name_pattern: str = DEFAULT_NAME_PATTERN
    seed: int = 0

    def __post_init__(self) -> None:
        if (
            min(self.count, self.arm_delay_s, self.backward, self.stops) < 0
            or min(self.seconds, self.stop_motion_s, self.stop_hold_s) <= 0
        ):
            raise ValueError(
                "splices need count, arm_delay_s, backward and stops >= 0, seconds, stop_motion_s and "
                f"stop_hold_s > 0, got {self}"
            )

    @property
    def adds(self) -> bool:
        """Whether a build adds any sequence."""
        return bool(self.count or self.backward or self.stops)


@dataclass
class SplicePlan:
    """The splices to simulate, and how the draw went."""

    specs: list[SequenceSpec]
    drawn: int  # candidates drawn
    refused: int  # of them, refused for limbs through the body


def window_candidates(specs: list[SequenceSpec], training: set[str], seconds: float) -> list[SequenceSpec]:
    """The motion-file sequences a window of ``seconds`` may be taken from: training ones, played at
    their own speed, not mirrored, not themselves spliced, long enough (a clip played backward's)."""
    frames = int(round(seconds * FPS))
    return [
        s
        for s in specs
        if s.name in training
        and s.kind == "file"
        and s.speed == 1.0
        and not s.mirrored
        and not s.upper_path
        and s.stop - s.start >= frames
    ]


def splice_candidates(
    specs: list[SequenceSpec], training: set[str], options: SpliceSettings
) -> list[SequenceSpec]:
    """The :func:`window_candidates` a splice may take its parts from: those whose names give the
    field the parts must differ in."""
    return [
        s
        for s in window_candidates(specs, training, options.seconds)
        if clip_group(Path(s.path).stem, options.field, options.name_pattern).startswith(f"{options.field}=")
    ]


def plan_splices(candidates: list[SequenceSpec], options: SpliceSettings) -> SplicePlan:
    """``options.count`` splices of ``candidates`` (:func:`splice_candidates`): the legs of one, the
    upper body of another whose ``options.field`` differs, windows drawn inside each, every one
    checked for limbs through the body (the mannequin's capsules)."""
    frames = int(round(options.seconds * FPS))
    group = {s.name: clip_group(Path(s.path).stem, options.field, options.name_pattern) for s in candidates}
    rng = np.random.default_rng(options.seed)
    specs: list[SequenceSpec] = []
    drawn = refused = 0
    if len(set(group.values())) < 2:
        return SplicePlan(specs, drawn, refused)
    while len(specs) < options.count and drawn < options.count * DRAWS_PER_SPLICE:
        drawn += 1
        # each part drawn on its own (the same content twice is drawn again below)
        legs, arms = (
            candidates[int(rng.integers(len(candidates)))],
            candidates[int(rng.integers(len(candidates)))],
        )
        start = legs.start + int(rng.integers(0, legs.stop - legs.start - frames + 1))
        upper_start = arms.start + int(rng.integers(0, arms.stop - arms.start - frames + 1))
        delay = (
            int(rng.integers(1, int(options.arm_delay_s * FPS) + 1)) * int(rng.choice([-1, 1]))
            if options.arm_delay_s >= 1 / FPS
            else 0
        )
        if group[legs.name] == group[arms.name]:
            continue
        spec = replace(
            legs,
            name=f"{SPLICE_PREFIX}{len(specs):03d}",
            start=start,
            stop=start + frames,
            upper_path=arms.path,
            upper_start=upper_start,
            arm_delay=delay,
        )
        if self_intersecting_frames(spec.motion()).any():
            refused += 1
            continue
        specs.append(spec)
    return SplicePlan(specs, drawn, refused)


def plan_backward(candidates: list[SequenceSpec], options: SpliceSettings) -> list[SequenceSpec]:
    """``options.backward`` windows of ``candidates`` (:func:`window_candidates`) played backward,
    each of ``options.seconds``, clip and window drawn at random (seeded)."""
    # not the splices' generator: their draw stays as it was
    return _drawn_windows(
        candidates, options.backward, options.seconds, [options.seed, 1], BACKWARD_PREFIX, backward=True
    )


def plan_stops(candidates: list[SequenceSpec], options: SpliceSettings) -> list[SequenceSpec]:
    """``options.stops`` windows of ``candidates`` (:func:`window_candidates` of
    ``options.stop_motion_s``), each then held still ``options.stop_hold_s``, clip and window drawn
    at random (seeded)."""
    hold = int(round(options.stop_hold_s * FPS))
    # neither the splices' generator nor the backward windows'
    return _drawn_windows(
        candidates, options.stops, options.stop_motion_s, [options.seed, 2], STOP_PREFIX, hold=hold
    )


def _drawn_windows(
    candidates: list[SequenceSpec], count: int, seconds: float, seed: list[int], prefix: str, **change
) -> list[SequenceSpec]:
    """``count`` windows of ``seconds`` of ``candidates``, clip and window drawn by a generator seeded
    ``seed``, named ``prefix`` and a number, each with ``change`` applied."""
    frames = int(round(seconds * FPS))
    rng = np.random.default_rng(seed)
    specs = []
    for i in range(count if candidates else 0):
        clip = candidates[int(rng.integers(len(candidates)))]
        start = clip.start + int(rng.integers(0, clip.stop - clip.start - frames + 1))
        specs.append(replace(clip, name=f"{prefix}{i:03d}", start=start, stop=start + frames, **change))
    return specs
