"""Matching a source skeleton's joints to the canonical ones by name: built-in naming schemes
(the best-scoring one is picked), or a user's joint map in YAML."""

from __future__ import annotations

import re
from pathlib import Path

from ..errors import MotionError, SkeletonMappingError
from ..input_files import read_input_text
from .skeleton import JOINT_NAMES

# Canonical joints that may be missing from a source; they then follow their parent rigidly.
OPTIONAL_JOINTS = frozenset({"spine2", "l_collar", "r_collar", "l_foot", "r_foot"})


def _lr(template: dict[str, list[str]]) -> dict[str, list[str]]:
    """Expand '{s}'/'{S}' placeholders into left and right entries of a naming scheme."""
    out: dict[str, list[str]] = {}
    for key, names in template.items():
        if "{side}" in key:
            for side, s, S, full in (("l", "l", "L", "Left"), ("r", "r", "R", "Right")):
                out[key.replace("{side}", side)] = [n.format(s=s, S=S, Side=full) for n in names]
        else:
            out[key] = names
    return out


# Canonical joint -> accepted source names (matched case-insensitively, namespace prefix stripped).
NAMING_SCHEMES: dict[str, dict[str, list[str]]] = {
    "smpl": _lr(
        {
            "pelvis": ["pelvis", "m_avg_pelvis"],
            "spine1": ["spine1", "m_avg_spine1"],
            "spine2": ["spine2", "m_avg_spine2"],
            "spine3": ["spine3", "m_avg_spine3"],
            "neck": ["neck", "m_avg_neck"],
            "head": ["head", "m_avg_head"],
            "{side}_hip": ["{s}_hip", "{S}_Hip", "{Side}_hip", "m_avg_{S}_hip"],
            "{side}_knee": ["{s}_knee", "{Side}_knee", "m_avg_{S}_knee"],
            "{side}_ankle": ["{s}_ankle", "{Side}_ankle", "m_avg_{S}_ankle"],
            "{side}_foot": ["{s}_foot", "{Side}_foot", "m_avg_{S}_foot"],
            "{side}_collar": ["{s}_collar", "{Side}_collar", "m_avg_{S}_collar"],
            "{side}_shoulder": ["{s}_shoulder", "{Side}_shoulder", "m_avg_{S}_shoulder"],
            "{side}_elbow": ["{s}_elbow", "{Side}_elbow", "m_avg_{S}_elbow"],
            "{side}_wrist": ["{s}_wrist", "{Side}_wrist", "m_avg_{S}_wrist"],
        }
    ),
    # CMU as converted to BVH by most public sets (e.g. 02_01): LeftUpLeg / LowerBack / LeftArm ...
    "cmu": _lr(
        {
            "pelvis": ["Hips"],
            "spine1": ["LowerBack"],
            "spine2": ["Spine"],
            "spine3": ["Spine1"],
            "neck": ["Neck"],
            "head": ["Head"],
            "{side}_hip": ["{Side}UpLeg"],
            "{side}_knee": ["{Side}Leg"],
            "{side}_ankle": ["{Side}Foot"],
            "{side}_foot": ["{Side}ToeBase"],
            "{side}_collar": ["{Side}Shoulder"],
            "{side}_shoulder": ["{Side}Arm"],
            "{side}_elbow": ["{Side}ForeArm"],
            "{side}_wrist": ["{Side}Hand"],
        }
    ),
    # CMU's "3dsMax-friendly" naming (e.g. 131_01): LeftHip / lowerback / Chest / LeftCollar ...
    "cmu_max": _lr(
        {
            "pelvis": ["Hips"],
            "spine1": ["lowerback"],
            "spine2": ["Chest"],
            "spine3": ["Chest2"],
            "neck": ["lowerneck", "Neck"],
            "head": ["Head"],
            "{side}_hip": ["{Side}Hip"],
            "{side}_knee": ["{Side}Knee"],
            "{side}_ankle": ["{Side}Ankle"],
            "{side}_foot": ["{Side}Toe"],
            "{side}_collar": ["{Side}Collar"],
            "{side}_shoulder": ["{Side}Shoulder"],
            "{side}_elbow": ["{Side}Elbow"],
            "{side}_wrist": ["{Side}Wrist"],
        }
    ),
    # Bandai-Namco research motion sets: Hips, Spine, Chest, UpperLeg_L ... (one spine joint fewer).
    "bandai_namco": _lr(
        {
            "pelvis": ["Hips"],
            "spine1": ["Spine"],
            "spine3": ["Chest"],
            "neck": ["Neck"],
            "head": ["Head"],
            "{side}_hip": ["UpperLeg_{S}"],
            "{side}_knee": ["LowerLeg_{S}"],
            "{side}_ankle": ["Foot_{S}"],
            "{side}_foot": ["Toes_{S}", "Toe_{S}"],
            "{side}_collar": ["Shoulder_{S}"],
            "{side}_shoulder": ["UpperArm_{S}"],
            "{side}_elbow": ["LowerArm_{S}"],
            "{side}_wrist": ["Hand_{S}"],
        }
    ),
    # Mixamo (names carry a "mixamorig:" prefix, or "mixamorig_" / "mixamorig" in glTF files,
    # stripped before matching).
    "mixamo": _lr(
        {
            "pelvis": ["Hips"],
            "spine1": ["Spine"],
            "spine2": ["Spine1"],
            "spine3": ["Spine2"],
            "neck": ["Neck"],
            "head": ["Head"],
            "{side}_hip": ["{Side}UpLeg"],
            "{side}_knee": ["{Side}Leg"],
            "{side}_ankle": ["{Side}Foot"],
            "{side}_foot": ["{Side}ToeBase"],
            "{side}_collar": ["{Side}Shoulder"],
            "{side}_shoulder": ["{Side}Arm"],
            "{side}_elbow": ["{Side}ForeArm"],
            "{side}_wrist": ["{Side}Hand"],
        }
    ),
    # Blender-style side suffixes ("UpperLeg.L", matched as "upperleg_l"), as Quaternius's and other
    # hand-rigged game characters name them: Pelvis, Spine1, Spine2, Collar.L, UpperArm.L ...
    "blender": _lr(
        {
            "pelvis": ["Pelvis", "Hips"],
            "spine1": ["Spine", "Spine1"],
            "spine3": ["Chest", "Spine2"],
            "neck": ["Neck"],
            "head": ["Head"],
            "{side}_hip": ["UpperLeg_{S}", "Thigh_{S}"],
            "{side}_knee": ["LowerLeg_{S}", "Shin_{S}"],
            "{side}_ankle": ["Foot_{S}"],
            "{side}_foot": ["Toes_{S}", "Toe_{S}"],
            "{side}_collar": ["Collar_{S}", "Shoulder_{S}"],
            "{side}_shoulder": ["UpperArm_{S}"],
            "{side}_elbow": ["LowerArm_{S}", "Forearm_{S}"],
            "{side}_wrist": ["Hand_{S}"],
        }
    ),
    "canonical": {n: [n] for n in JOINT_NAMES},
}


# Mixamo's prefix as exporters write it: "mixamorig:Hips", numbered "mixamorig1:Hips", and in glTF
# files whose exporter replaced or dropped the colon, "mixamorig_Hips" and "mixamorigHips" (three.js).
_MIXAMO_PREFIX = re.compile(r"^mixamorig\d*[_:]?")


_DOT_SIDE = re.compile(r"\.([lr])$")  # Blender's ".L" / ".R" side suffix, matched as "_l" / "_r"
# words in joint names that only an animal's rig has: a non-human skeleton is refused as such
_ANIMAL_WORDS = re.compile(r"tail|paw|hoof|wing|snout|muzzle|ear_?\d", re.IGNORECASE)


def _key(name: str) -> str:
    """A joint name as matched: case-folded, without a namespace ("ns:") or Mixamo prefix, with a
    Blender side suffix (".L") written as "_l"."""
    return _DOT_SIDE.sub(r"_\1", _MIXAMO_PREFIX.sub("", name.split(":")[-1].strip().lower()))


def resolve_joint_map(
    names: list[str], path: str, custom_map: dict[str, str] | None = None
) -> tuple[str, dict[str, int]]:
    """Pick a naming scheme (or apply ``custom_map``): returns (scheme name, canonical -> source index)."""
    lookup: dict[str, int] = {}
    for i, n in enumerate(names):
        lookup.setdefault(_key(n), i)
    if custom_map is not None:
        unknown = sorted(set(custom_map) - set(JOINT_NAMES))
        if unknown:
            raise SkeletonMappingError(
                path,
                f"joint map names unknown canonical joints {unknown}; canonical joints are "
                f"{list(JOINT_NAMES)}",
            )
        missing_src = sorted(src for src in custom_map.values() if _key(src) not in lookup)
        if missing_src:
            raise SkeletonMappingError(
                path, f"joint map refers to joints {missing_src} that the file does not have"
            )
        mapping = {c: lookup[_key(s)] for c, s in custom_map.items()}
        _check_required(mapping, path, "custom", names)
        return "custom", mapping
    best: tuple[int, str, dict[str, int]] | None = None
    for scheme, table in NAMING_SCHEMES.items():
        mapping = {}
        for canon, candidates in table.items():
            idx = next((lookup[_key(c)] for c in candidates if _key(c) in lookup), None)
            if idx is not None:
                mapping[canon] = idx
        required_ok = all(j in mapping for j in JOINT_NAMES if j not in OPTIONAL_JOINTS)
        score = len(mapping) + (100 if required_ok else 0)
        if best is None or score > best[0]:
            best = (score, scheme, mapping)
    assert best is not None
    _check_required(best[2], path, best[1], names)
    return best[1], best[2]


def _check_required(mapping: dict[str, int], path: str, scheme: str, names: list[str]) -> None:
    """Refuse a mapping without every required joint; a rig whose names say it is an animal's (a
    tail, paws) is refused as not human, since no joint map makes it one."""
    missing = [j for j in JOINT_NAMES if j not in mapping and j not in OPTIONAL_JOINTS]
    animal = [n for n in names if _ANIMAL_WORDS.search(n)]
    if missing and animal:
        raise SkeletonMappingError(
            path,
            f"not a human skeleton: its joints include {animal[:3]}, an animal's, and {len(missing)} of the "
            "canonical human joints are missing; only a two-legged human rig (hips, knees, ankles, spine, "
            "shoulders, elbows, wrists) can be read as a character or a motion",
        )
    if missing:
        raise SkeletonMappingError(
            path,
            f"unknown skeleton: could not map canonical joints {missing} (closest naming scheme: {scheme}). "
            "Pass a joint map YAML ('canonical_name: source_joint_name' per line) with --joint-map.",
        )


def load_joint_map(path: str | Path) -> dict[str, str]:
    """A YAML joint map (canonical joint: source joint)."""
    import yaml

    path = Path(path)
    text = read_input_text(path, what="a joint map")
    try:
        data = yaml.safe_load(text)
    except (yaml.YAMLError, RecursionError) as exc:
        raise MotionError(path, f"cannot read joint map: {exc}") from None
    if not isinstance(data, dict) or not all(
        isinstance(k, str) and isinstance(v, str) for k, v in data.items()
    ):
        raise MotionError(path, "joint map must be a mapping 'canonical_joint: source_joint'")
    return data
