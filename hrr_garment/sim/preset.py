"""Presets (configs/presets/*.yaml): what a dataset build simulates and how a model trains on it.

A preset gives the garment resolution, clip length, how many procedural clips of each kind, motion
files (paths, globs, folders, archives: see :mod:`.sources`), split fractions and the clip groups
they hold out whole, augmentation, bodies, a seed, simulator overrides and training overrides.
``extends:`` starts from another preset, so a variant names only what it changes; the sequences it
asks for are planned by :mod:`.plan`.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from ..errors import InputError
from ..motion.licences import SOURCES
from ..motion.motion import FPS
from ..motion.synth import KINDS
from ..motion.synth.posture import POSTURES
from ..settings import deep_merge
from .sources import DEFAULT_NAME_PATTERN

CONFIG_DIR = Path(__file__).resolve().parents[2] / "configs"


@dataclass(frozen=True)
class Preset:
    """A dataset and training preset (configs/presets/NAME.yaml)."""

    name: str
    vertices: int
    seconds: float
    sequences: dict[str, int]
    splits: dict[str, float] = field(default_factory=lambda: {"val": 0.1, "test": 0.1})
    seed: int = 0
    sim: dict = field(default_factory=dict)
    train: dict = field(default_factory=dict)  # hrr-train overrides, shaped like configs/train.yaml
    # motion files, globs, folders, archives; an entry may declare its source ({path: ..., source:
    # cmu}, motion/licences.py), else the shared folder it names or the user's own is its source
    motions: list[str | dict] = field(default_factory=list)
    split_by: str | None = None  # a field of name_pattern whose groups are held out whole
    # more fields held out whole beside it, each with its own fractions ({content: {test: 0.08}}):
    # a sequence tests where any field's split tests it; files whose names lack the field train
    also_hold_out: dict = field(default_factory=dict)
    name_pattern: str = DEFAULT_NAME_PATTERN
    # add each sequence mirrored left-right: "simulate" (true) simulates the mirrored motion, "reflect"
    # reflects the source's simulation (no solver time, but not the mirrored motion's simulation under
    # an unconverged solver and an asymmetric triangulation: docs/dataset.md), false adds none
    mirror: bool | str = False
    speed_warps: list[float] = field(default_factory=list)  # motion files re-timed and simulated again
    base: str = ""  # the preset file's folder: relative motion entries resolve against it first
    bodies: dict = field(
        default_factory=dict
    )  # which bodies the sequences stand on (sim/body_plan.py); none: the mannequin
    # which cloths the sequences are simulated in (sim/material_plan.py); none: the sim section's
    materials: dict = field(default_factory=dict)
    # more training motion from the training clips' parts (sim/augment.py): {count, seconds,
    # arm_delay_s, field, backward, stops, stop_motion_s, stop_hold_s}
    splices: dict = field(default_factory=dict)
    # build only from motion whose source allows a sold product (CMU, procedural, the user's own):
    # entries from other sources are left out, and the build says which
    commercial_only: bool = False
    # how the procedural clips carry the body: "upright" (the kinds' own) or "drawn" (each clip a
    # performer's pelvis tilt, chest lean and collars drawn with its seed: motion/synth/posture.py)
    posture: str = "upright"


def preset_names() -> list[str]:
    """The presets in configs/presets."""
    return sorted(p.stem for p in (CONFIG_DIR / "presets").glob("*.yaml"))


def load_preset(name_or_path: str) -> Preset:
    """A preset by name (configs/presets/NAME.yaml) or by path to a YAML file."""
    path = Path(name_or_path)
    if not path.suffix:
        path = CONFIG_DIR / "presets" / f"{name_or_path}.yaml"
        if not path.is_file():
            raise InputError(
                name_or_path, f"unknown preset; choose one of {', '.join(preset_names())} or give a YAML file"
            )
    try:
        data = _preset_data(path)
        preset = Preset(**data, base=str(path.resolve().parent))
    except (OSError, yaml.YAMLError, TypeError) as exc:
        raise InputError(path, f"not a valid preset: {exc}") from None
    bad_warps = [w for w in preset.speed_warps if not (isinstance(w, (int, float)) and 0.25 <= w <= 4.0)]
    if bad_warps:
        raise InputError(path, f"speed_warps must be factors between 0.25 and 4, got {bad_warps}")
    _check_also_hold_out(path, preset)
    _check_splices(path, preset)
    from .material_plan import MaterialPlan  # imports this module's users: here, not at the top

    MaterialPlan.from_preset(preset.materials, str(path))
    _check_motions(path, preset)
    if mirror_mode(preset.mirror) is None:
        raise InputError(
            path,
            f"mirror: {preset.mirror!r} is not one of {', '.join(repr(m) for m in MIRROR_MODES)} (or true / "
            "false)",
        )
    unknown = sorted(set(preset.sequences) - set(KINDS))
    if unknown:
        raise InputError(path, f"unknown motion kinds {unknown}; available: {', '.join(KINDS)}")
    if preset.posture not in POSTURES:
        raise InputError(path, f"posture: {preset.posture!r} is not one of {', '.join(map(repr, POSTURES))}")
    return preset


MIRROR_MODES = ("simulate", "reflect")


def mirror_mode(value: bool | str | None) -> str | None:
    """A preset's ``mirror`` as a mode: "simulate" (``true`` too), "reflect", "" (``false``, absent);
    None where it is none of these."""
    if value is True:
        return "simulate"
    if value in (False, None, ""):
        return ""
    return value if value in MIRROR_MODES else None


SPLICE_KEYS = {
    "count": int,
    "seconds": (int, float),
    "arm_delay_s": (int, float),
    "field": str,
    "backward": int,
    "stops": int,
    "stop_motion_s": (int, float),
    "stop_hold_s": (int, float),
}


def _check_splices(path: Path, preset: Preset) -> None:
    """An InputError unless ``splices`` holds only known keys of the right types and a field of the
    name pattern."""
    bad = {
        k: v
        for k, v in preset.splices.items()
        if k not in SPLICE_KEYS
        or not isinstance(v, SPLICE_KEYS[k])
        or isinstance(v, bool)
        or (k != "field" and v < 0)
    }
    if bad:
        raise InputError(
            path,
            f"splices: {bad!r} not understood; it takes {', '.join(SPLICE_KEYS)} (numbers >= 0, a field "
            "name)",
        )
    lengths = ("seconds", "stop_motion_s", "stop_hold_s")
    short = [k for k in lengths if k in preset.splices and round(preset.splices[k] * FPS) < 1]
    if short:
        raise InputError(path, f"splices: {', '.join(short)} must be at least one frame (1/{FPS:g} s)")
    name_field = preset.splices.get("field", "content")
    if preset.splices.get("count") and name_field not in re.compile(preset.name_pattern).groupindex:
        raise InputError(path, f"splices: field {name_field!r} is not a field of the name pattern")


def _check_motions(path: Path, preset: Preset) -> None:
    """An InputError unless every motion entry is a path or ``{path, source}`` with a known source."""
    for entry in preset.motions:
        if isinstance(entry, str):
            continue
        if (
            not isinstance(entry, dict)
            or set(entry) - {"path", "source"}
            or not isinstance(entry.get("path"), str)
        ):
            raise InputError(path, f"motions: {entry!r} is neither a path nor {{path: ..., source: ...}}")
        if entry.get("source") not in SOURCES:
            known = ", ".join(SOURCES)
            raise InputError(
                path, f"motions: {entry['path']!r} declares source {entry.get('source')!r}; known: {known}"
            )
    if not isinstance(preset.commercial_only, bool):
        raise InputError(path, f"commercial_only must be true or false, got {preset.commercial_only!r}")


def _check_also_hold_out(path: Path, preset: Preset) -> None:
    """An InputError unless ``also_hold_out`` maps fields of the name pattern to val / test fractions."""
    fields = set(re.compile(preset.name_pattern).groupindex)
    for name, fractions in preset.also_hold_out.items():
        if name not in fields:
            raise InputError(
                path,
                f"also_hold_out: {name!r} is not a field of the name pattern ({', '.join(sorted(fields))})",
            )
        if (
            not isinstance(fractions, dict)
            or set(fractions) - {"val", "test"}
            or not all(isinstance(v, (int, float)) and 0.0 <= v < 0.5 for v in fractions.values())
        ):
            raise InputError(
                path, f"also_hold_out: {name!r} takes val and test fractions from 0 to 0.5, got {fractions!r}"
            )


def _preset_data(path: Path, depth: int = 0) -> dict:
    """A preset file's values; ``extends: NAME`` starts from another preset's (NAME.yaml beside the
    file, else the built-in preset NAME; its keys replaced
    by this file's, one level deep; ``train``, a training config, merged section by section), so a
    variant names only what it changes."""
    data = yaml.safe_load(path.read_text(encoding="utf-8"))
    if not isinstance(data, dict):
        raise TypeError("a preset is a mapping of keys to values")
    parent = data.pop("extends", None)
    if parent is None:
        return data
    if depth > 4 or not isinstance(parent, str):
        raise TypeError(f"extends must name one preset (and not loop), got {parent!r}")
    parent_path = path.parent / f"{parent}.yaml" if not Path(parent).suffix else path.parent / parent
    if (
        not Path(parent).suffix and not parent_path.is_file()
    ):  # a user's own file extends a built-in by its name
        parent_path = CONFIG_DIR / "presets" / f"{parent}.yaml"
    base = _preset_data(parent_path, depth + 1)
    return {
        **base,
        **data,
        **({"train": deep_merge(base.get("train") or {}, data["train"])} if "train" in data else {}),
    }


#: the preset's settings that decide which sequences a dataset holds and how they split
PLAN_FIELDS = (
    "vertices",
    "seconds",
    "sequences",
    "motions",
    "name_pattern",
    "split_by",
    "splits",
    "also_hold_out",
    "mirror",
    "speed_warps",
    "bodies",
    "materials",
    "splices",
    "seed",
    "commercial_only",
    "posture",
)


def plan_record(preset: Preset) -> dict:
    """:data:`PLAN_FIELDS` of ``preset`` as a dataset records them (JSON's types), so that a dataset
    made before the preset was edited is told apart (hrr_garment/pipeline/simulate.py)."""
    record = {k: getattr(preset, k) for k in PLAN_FIELDS}
    for later in ("commercial_only", "materials"):  # added later: datasets made before record neither
        if not record[later]:
            del record[later]
    if record["posture"] == "upright":  # added later too, at its default
        del record["posture"]
    return json.loads(json.dumps(record))
