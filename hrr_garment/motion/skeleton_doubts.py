"""Does a source skeleton look like its joint names? (issue 48)

Joints are matched to the canonical skeleton by name (:mod:`.joint_maps`), so a file whose names
were swapped between two joints, or a joint map that names the wrong bones, retargets without a
complaint and plays a body folded the wrong way: a dress then ends a third inside it. Three
checks of the rest pose catch that, each naming the joints:

* **the hierarchy**: every mapped joint lies below the joint its canonical parent maps to (a knee
  below its own hip, an elbow below its own shoulder); a swap between two chains or along one
  breaks it;
* **left against right**: the thigh, shin, upper arm and forearm of the two sides within 25 % of
  each other in length;
* **the sides** (where the rest pose stands: :func:`~.retarget.rest_is_standing`): the joints named
  left on the side the feet point left of.

Doubts are warnings (:class:`~hrr_garment.errors.SkeletonWarning`), not errors: odd rigs exist,
and a custom joint map (``--joint-map``) fixes a real mismatch.
"""

from __future__ import annotations

import warnings

import numpy as np

from ..errors import SkeletonWarning
from .retarget import rest_is_standing
from .skeleton import JOINT_INDEX, JOINT_NAMES, PARENTS

SIDE_BONES = (("hip", "knee"), ("knee", "ankle"), ("shoulder", "elbow"), ("elbow", "wrist"))
MAX_SIDE_RATIO = 1.25  # one side's bone this much longer than the other's: not the same bone
SIDE_SLACK = 0.25  # x the hips' width: how far a left joint may stand right of its right twin (feet crossed)


def _ancestors(parents: list[int], joint: int) -> set[int]:
    seen: set[int] = set()
    while joint >= 0 and joint not in seen:
        seen.add(joint)
        joint = parents[joint]
    return seen


def _hierarchy_doubts(names: list[str], parents: list[int], mapping: dict[str, int]) -> list[str]:
    doubts = []
    for joint, parent in zip(JOINT_NAMES, PARENTS):
        if parent < 0 or joint not in mapping or JOINT_NAMES[parent] not in mapping:
            continue
        src, src_parent = mapping[joint], mapping[JOINT_NAMES[parent]]
        if src != src_parent and src_parent not in _ancestors(parents, src):
            doubts.append(
                f"{names[src]!r} (taken as {joint}) is not below {names[src_parent]!r} (taken as "
                f"{JOINT_NAMES[parent]}) in the hierarchy"
            )
    return doubts


def _length_doubts(names: list[str], rest: np.ndarray, mapping: dict[str, int]) -> list[str]:
    doubts = []
    for a, b in SIDE_BONES:
        keys = [(f"{s}_{a}", f"{s}_{b}") for s in "lr"]
        if not all(k in mapping for pair in keys for k in pair):
            continue
        lengths = [float(np.linalg.norm(rest[mapping[tip]] - rest[mapping[base]])) for base, tip in keys]
        if min(lengths) <= 0 or max(lengths) / min(lengths) > MAX_SIDE_RATIO:
            doubts.append(
                f"the left {a}-{b} bone ({names[mapping[keys[0][0]]]!r} to {names[mapping[keys[0][1]]]!r}, "
                f"{lengths[0]:.3g}) and the right one ({names[mapping[keys[1][0]]]!r} to "
                f"{names[mapping[keys[1][1]]]!r}, {lengths[1]:.3g}) differ by more than "
                f"{MAX_SIDE_RATIO - 1:.0%}"
            )
    return doubts


def _side_doubts(names: list[str], rest: np.ndarray, mapping: dict[str, int]) -> list[str]:
    """The left joints on the character's left: the side of up x forward, forward being where the
    feet point and up the spine."""
    needed = ("pelvis", "neck", "l_ankle", "r_ankle", "l_foot", "r_foot")
    if not all(k in mapping for k in needed):
        return []
    pelvis = rest[mapping["pelvis"]]
    up = rest[mapping["neck"]] - pelvis
    forward = sum(rest[mapping[f"{s}_foot"]] - rest[mapping[f"{s}_ankle"]] for s in "lr")
    left = np.cross(up, forward)  # Y up, Z forward: +X is the character's left
    if np.linalg.norm(left) < 1e-9:
        return []
    left /= np.linalg.norm(left)
    # a joint is on the wrong side when it is there by more than a quarter of the hips' width: feet
    # together or crossed in a rest pose (ankles 0.18 apart beside hips 2.2 apart, CMU 02_01 through
    # Blender's FBX and glTF) are not a swap, which puts the left joint a whole width to the right
    hips = (
        (rest[mapping["l_hip"]] - rest[mapping["r_hip"]]) @ left
        if "l_hip" in mapping and "r_hip" in mapping
        else 0.0
    )
    slack = SIDE_SLACK * abs(float(hips))
    wrong = [
        f"{names[mapping[f'l_{j}']]!r} (taken as l_{j})"
        for j in ("hip", "knee", "ankle", "shoulder", "elbow", "wrist")
        if f"l_{j}" in mapping
        and f"r_{j}" in mapping
        and (rest[mapping[f"l_{j}"]] - rest[mapping[f"r_{j}"]]) @ left < -slack
    ]
    return [f"{', '.join(wrong)} on the character's right (its feet point the other way)"] if wrong else []


def skeleton_doubts(
    names: list[str], parents: list[int], rest: np.ndarray, mapping: dict[str, int]
) -> list[str]:
    """Why a skeleton (joint ``names``, ``parents``, ``rest`` positions, any unit) does not look like
    what ``mapping`` (canonical name -> joint index) takes its joints for; empty when it does."""
    doubts = _hierarchy_doubts(names, parents, mapping) + _length_doubts(names, rest, mapping)
    by_index = {JOINT_INDEX[k]: v for k, v in mapping.items() if k in JOINT_INDEX}
    return doubts + (_side_doubts(names, rest, mapping) if rest_is_standing(rest, by_index) else [])


def doubts_sentence(doubts: list[str]) -> str:
    """The doubts as one clause of a message, with the way out."""
    return (
        f"the skeleton does not look like its joint names: {'; '.join(doubts)} (a joint map, --joint-map, "
        "says which joint is which)"
    )


def warn_doubts(path: str, doubts: list[str]) -> None:
    """A :class:`SkeletonWarning` naming the file and each doubt of :func:`skeleton_doubts`."""
    if doubts:
        warnings.warn(f"{path}: {doubts_sentence(doubts)}", SkeletonWarning, stacklevel=3)
