"""What a dataset build simulates: presets (configs/presets/*.yaml) and the list of sequences.

A preset gives the garment resolution, clip length, how many procedural clips of each kind, motion
files (paths, globs, folders, archives: see :mod:`.sources`), split fractions and the clip groups
they hold out whole, augmentation, a seed and simulator overrides. ``plan_sequences`` turns it
(plus any motion files or kinds given on the command line) into named, seeded
:class:`SequenceSpec` items, the same on every run, so a re-run finds the sequences it already
finished.
"""

from __future__ import annotations

import hashlib
import json
import re
from dataclasses import asdict, dataclass, field
from pathlib import Path

import yaml

from ..errors import HRRError, InputError, MotionError
from ..motion.compose import arm_delayed, played_backward, spliced
from ..motion.edit import retimed
from ..motion.io import load_motion
from ..motion.motion import Motion
from ..motion.synth import KINDS, synthesize
from ..settings import deep_merge
from .augment import SpliceOptions
from .sources import DEFAULT_NAME_PATTERN, clip_group, resolve_motion_entries

CONFIG_DIR = Path(__file__).resolve().parents[2] / "configs"
MIN_CLIP_FRAMES = 15  # half a second: shorter clips are mostly lead-in
FILE_PIECE_S = 12.0  # longer motion files are simulated in pieces of at most this length


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
    motions: list[str] = field(default_factory=list)  # motion files, globs, folders, archives
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
    bodies: dict = field(default_factory=dict)  # which bodies the sequences stand on (sim/bodies.py); none: the mannequin
    # more training motion from the training clips' parts (sim/augment.py): {count, seconds, arm_delay_s, field}
    splices: dict = field(default_factory=dict)


def preset_names() -> list[str]:
    """The presets in configs/presets."""
    return sorted(p.stem for p in (CONFIG_DIR / "presets").glob("*.yaml"))


def load_preset(name_or_path: str) -> Preset:
    """A preset by name (configs/presets/NAME.yaml) or by path to a YAML file."""
    path = Path(name_or_path)
    if not path.suffix:
        path = CONFIG_DIR / "presets" / f"{name_or_path}.yaml"
        if not path.is_file():
            raise InputError(name_or_path, f"unknown preset; choose one of {', '.join(preset_names())} or give a YAML file")
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
    if mirror_mode(preset.mirror) is None:
        raise InputError(path, f"mirror: {preset.mirror!r} is not one of {', '.join(repr(m) for m in MIRROR_MODES)} (or true / false)")
    unknown = sorted(set(preset.sequences) - set(KINDS))
    if unknown:
        raise InputError(path, f"unknown motion kinds {unknown}; available: {', '.join(KINDS)}")
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


SPLICE_KEYS = {"count": int, "seconds": (int, float), "arm_delay_s": (int, float), "field": str, "backward": int}


def _check_splices(path: Path, preset: Preset) -> None:
    """An InputError unless ``splices`` holds only known keys of the right types and a field of the name pattern."""
    bad = {k: v for k, v in preset.splices.items() if k not in SPLICE_KEYS or not isinstance(v, SPLICE_KEYS[k])
           or isinstance(v, bool) or (k != "field" and v < 0)}
    if bad:
        raise InputError(path, f"splices: {bad!r} not understood; it takes {', '.join(SPLICE_KEYS)} (numbers >= 0, a field name)")
    name_field = preset.splices.get("field", "content")
    if (preset.splices.get("count") or preset.splices.get("backward")) and name_field not in re.compile(preset.name_pattern).groupindex:
        raise InputError(path, f"splices: field {name_field!r} is not a field of the name pattern")


def _check_also_hold_out(path: Path, preset: Preset) -> None:
    """An InputError unless ``also_hold_out`` maps fields of the name pattern to val / test fractions."""
    fields = set(re.compile(preset.name_pattern).groupindex)
    for name, fractions in preset.also_hold_out.items():
        if name not in fields:
            raise InputError(path, f"also_hold_out: {name!r} is not a field of the name pattern ({', '.join(sorted(fields))})")
        if not isinstance(fractions, dict) or set(fractions) - {"val", "test"} or not all(
                isinstance(v, (int, float)) and 0.0 <= v < 0.5 for v in fractions.values()):
            raise InputError(path, f"also_hold_out: {name!r} takes val and test fractions from 0 to 0.5, got {fractions!r}")


def _preset_data(path: Path, depth: int = 0) -> dict:
    """A preset file's values; ``extends: NAME`` starts from another preset's (its keys replaced
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
    base = _preset_data(parent_path, depth + 1)
    return {**base, **data, **({"train": deep_merge(base.get("train") or {}, data["train"])} if "train" in data else {})}


# SequenceSpec fields added after parts were first keyed, with their defaults: a spec at the default
# hashes as before the field existed
LATER_FIELDS = {"speed": 1.0, "source_fps": None, "body": "", "mirrored": False, "upper_path": "", "upper_start": 0,
                "arm_delay": 0, "backward": False}


@dataclass(frozen=True)
class SequenceSpec:
    """One sequence to simulate: a procedural clip (kind, seed, seconds) or a piece of a file."""

    name: str
    kind: str  # a procedural kind, or "file"
    seed: int = 0
    seconds: float = 0.0
    path: str = ""
    start: int = 0  # frame range of the file's 30 fps clip (after any speed warp)
    stop: int = 0
    speed: float = 1.0  # the file's motion played this much faster (a speed-warp augmentation)
    source_fps: float | None = None  # the file's frame rate where it carries none (--fps)
    body: str = ""  # the name of the body it is simulated on (sim/bodies.py); "": the mannequin
    mirrored: bool = False  # the motion reflected left-right (a preset's ``mirror: simulate``)
    # a splice (sim/augment.py): the spine, head and arms from this file's frames from upper_start on
    upper_path: str = ""
    upper_start: int = 0
    arm_delay: int = 0  # frames the left arm (> 0) or the right arm (< 0) plays late
    backward: bool = False  # the frames played in reverse order (sim/augment.py)

    def motion(self) -> Motion:
        if self.kind == "file":
            clip = load_file_motion(self.path, self.speed, self.source_fps).slice(self.start, self.stop)
            if self.upper_path:
                upper = load_file_motion(self.upper_path, self.speed, self.source_fps)
                clip = spliced(clip, upper.slice(self.upper_start, self.upper_start + self.stop - self.start))
        else:
            clip = synthesize(self.kind, self.seconds, seed=self.seed)
        if self.arm_delay:
            clip = arm_delayed(clip, "l" if self.arm_delay > 0 else "r", abs(self.arm_delay))
        if self.backward:
            clip = played_backward(clip)
        return clip.mirrored() if self.mirrored else clip

    def key(self, extra: dict) -> str:
        """Content hash of everything that determines the simulated result."""
        # Defaults of fields added later stay out, so earlier sequences keep their keys.
        spec = {k: v for k, v in asdict(self).items() if not (k in LATER_FIELDS and v == LATER_FIELDS[k])}
        payload = {"spec": spec, **extra}
        if self.kind == "file":
            payload["file_sha1"] = hashlib.sha1(Path(self.path).read_bytes()).hexdigest()
        if self.upper_path:
            payload["upper_sha1"] = hashlib.sha1(Path(self.upper_path).read_bytes()).hexdigest()
        return hashlib.sha256(json.dumps(payload, sort_keys=True, default=str).encode()).hexdigest()[:16]


def load_file_motion(path: str, speed: float = 1.0, source_fps: float | None = None) -> Motion:
    """A motion file at 30 fps, played ``speed`` times faster (resampled; features follow)."""
    return retimed(load_motion(path, source_fps=source_fps), speed)


def on_body(name: str, body: str) -> str:
    """The name of a clip's sequence on one of the several bodies it is simulated on (sim/bodies.py)."""
    return f"{name}__{body}"


def sequence_group(spec: SequenceSpec, preset: Preset) -> str:
    """The split group of a sequence: a procedural clip is its own, on every body it stands on (its
    copies on several bodies are named by :func:`on_body`), so that a preset's held-out clips do not
    depend on how many bodies each clip has; a file's comes from its name (every piece and speed
    warp of a file shares it)."""
    if spec.kind != "file":
        return spec.name.removesuffix(on_body("", spec.body)) if spec.body else spec.name
    return clip_group(Path(spec.path).stem, preset.split_by, preset.name_pattern)


def safe_name(text: str, empty: str = "clip") -> str:
    """``text`` as a name for a sequence or a body (letters, digits, ``_ . -``; ``empty`` if none is left)."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("_") or empty


def plan_sequences(preset: Preset, motions: list[str] | None = None, seconds: float | None = None,
                   source_fps: float | None = None) -> list[SequenceSpec]:
    """The preset's procedural clips and motion files, or, when ``motions`` is given, one clip per
    kind named there (repeat a kind for more) and every motion file named there (long files in
    pieces). The preset's speed warps apply to motion files either way; ``source_fps`` is the
    files' own frame rate where they carry none."""
    seconds = float(seconds or preset.seconds)
    counts: dict[str, int] = {}
    entries: list[str] = []
    if motions:
        for item in motions:
            if item in KINDS:
                counts[item] = counts.get(item, 0) + 1
            elif Path(item).suffix or Path(item).exists() or any(c in item for c in "*?[") or item.startswith("mocap:"):
                entries.append(item)
            else:
                raise InputError(item, f"neither a motion kind ({', '.join(KINDS)}) nor a motion file, folder or glob")
    else:
        counts = dict(preset.sequences)
        entries = list(preset.motions)
    specs = [SequenceSpec(f"{kind}_{i:03d}", kind, seed=preset.seed * 1000 + i, seconds=seconds)
             for kind, n in counts.items() for i in range(n)]
    files = resolve_motion_entries(entries, Path(preset.base) if preset.base and not motions else None)
    for path in files:
        for speed in (1.0, *preset.speed_warps):
            specs += _file_pieces(str(path), speed, source_fps)
    names = [s.name for s in specs]
    if len(set(names)) != len(names):
        raise HRRError(f"two motions would get the same sequence name: {sorted({n for n in names if names.count(n) > 1})}")
    if not specs:
        raise HRRError("nothing to simulate: the preset lists no sequences and no --motions were given")
    return specs


def _file_pieces(path: str, speed: float, source_fps: float | None) -> list[SequenceSpec]:
    """A motion file as sequences of at most FILE_PIECE_S (a short tail folds into the last)."""
    clip = load_file_motion(path, speed, source_fps)
    if clip.num_frames < MIN_CLIP_FRAMES:
        raise MotionError(path, f"motion too short to simulate: {clip.num_frames} frames at {clip.fps:g} fps "
                                f"(at least {MIN_CLIP_FRAMES})")
    piece = int(FILE_PIECE_S * clip.fps)
    starts = list(range(0, clip.num_frames, piece))
    if len(starts) > 1 and clip.num_frames - starts[-1] < MIN_CLIP_FRAMES:
        starts.pop()
    stem = safe_name(Path(path).stem) + (f"_x{speed:g}" if speed != 1.0 else "")
    specs = []
    for k, start in enumerate(starts):
        stop = starts[k + 1] if k + 1 < len(starts) else clip.num_frames
        suffix = f"_p{k}" if len(starts) > 1 else ""
        specs.append(SequenceSpec(f"{stem}{suffix}", "file", path=path, start=start, stop=stop, speed=speed,
                                  source_fps=source_fps))
    return specs


def build_options(preset: Preset, specs: list[SequenceSpec]) -> dict:
    """The preset's keyword arguments for :class:`~hrr_garment.sim.build.BuildOptions`: splits (by clip group when it names
    one), seed, mirroring and the provenance recorded in the file."""
    groups = {s.name: sequence_group(s, preset) for s in specs} if preset.split_by else None
    info: dict = {"preset": preset.name}
    if groups:  # recorded in the file: which groups were held out whole
        info.update(split_by=preset.split_by, groups=groups)
    mirror = mirror_mode(preset.mirror)
    if preset.speed_warps or mirror:
        info["augmentation"] = {"mirror": mirror, "speed_warps": list(preset.speed_warps)}
    also = {}
    for name, fractions in preset.also_hold_out.items():  # only the files whose names have the field
        by = {s.name: clip_group(Path(s.path).stem, name, preset.name_pattern) for s in specs if s.kind == "file"}
        by = {n: g for n, g in by.items() if g.startswith(f"{name}=")}
        also[name] = {"groups": by, "val": float(fractions.get("val", 0.0)), "test": float(fractions.get("test", 0.0))}
    if also:
        info["also_hold_out"] = also
    kinds = {s.name: s.kind for s in specs if s.kind != "file"}  # procedural clips: held out in distribution
    splices = None
    if preset.splices.get("count") or preset.splices.get("backward"):
        splices = SpliceOptions(**preset.splices, name_pattern=preset.name_pattern, seed=preset.seed)
        info.setdefault("augmentation", {"mirror": mirror, "speed_warps": list(preset.speed_warps)})["splices"] = preset.splices
    return {"splits": preset.splits, "seed": preset.seed, "groups": groups, "mirror": mirror, "info": info,
            "kinds": kinds or None, "also_hold_out": also or None, "splices": splices}
