"""What a dataset build simulates: the list of sequences a preset (:mod:`.preset`) asks for.

``plan_sequences`` turns a preset
(plus any motion files or kinds given on the command line) into named, seeded
:class:`SequenceSpec` items, the same on every run, so a re-run finds the sequences it already
finished.
"""

from __future__ import annotations

import hashlib
import json
import re
from dataclasses import asdict, dataclass
from pathlib import Path

from ..errors import HRRError, InputError, MotionError
from ..garment.material import Material
from ..motion.bvh_motion import bvh_reading
from ..motion.compose import arm_delayed, held_still, played_backward, spliced
from ..motion.edit import retimed
from ..motion.io import load_motion, native_frame_rate
from ..motion.motion import FPS, Motion
from ..motion.resample import kernel_width
from ..motion.synth import KINDS, synthesize
from .augment import AUGMENT_PREFIXES, SpliceSettings
from .motion_sources import file_sources, sourced_entries
from .preset import Preset, mirror_mode, plan_record
from .sources import clip_group

ANTI_ALIASED = "anti-aliased"  # the part key's mark of a faster capture read low-pass filtered
REFERENCE_DROPPED = "reference frames dropped"  # and of a file whose leading T-pose the reader drops
MIN_CLIP_FRAMES = 15  # half a second: shorter clips are mostly lead-in
FILE_PIECE_S = 12.0  # longer motion files are simulated in pieces of at most this length


# SequenceSpec fields added after parts were first keyed, with their defaults: a spec at the default
# hashes as before the field existed
LATER_FIELDS = {
    "speed": 1.0,
    "source_fps": None,
    "body_name": "",
    "mirrored": False,
    "upper_path": "",
    "upper_start": 0,
    "arm_delay": 0,
    "backward": False,
    "material": None,
    "hold": 0,
    "posture": "upright",
}
# SequenceSpec fields renamed since: each hashes under its old name, so its sequences keep their keys
KEYED_AS = {"body_name": "body"}


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
    body_name: str = ""  # the name of the body it is simulated on (sim/body_plan.py); "": the mannequin
    mirrored: bool = False  # the motion reflected left-right (a preset's ``mirror: simulate``)
    # a splice (sim/augment.py): the spine, head and arms from this file's frames from upper_start on
    upper_path: str = ""
    upper_start: int = 0
    arm_delay: int = 0  # frames the left arm (> 0) or the right arm (< 0) plays late
    backward: bool = False  # the frames played in reverse order (sim/augment.py)
    # the cloth it is simulated in (sim/material_plan.py); None: the build's own (SimSettings.material)
    material: Material | None = None
    hold: int = 0  # frames its last pose is held after the clip: the body stops dead (sim/augment.py)
    # a procedural clip's carriage: "upright" (the kind's own body) or "drawn" with its seed (a
    # preset's ``posture``, motion/synth/posture.py)
    posture: str = "upright"

    @property
    def frames(self) -> int:
        """The frames its motion plays at 30 fps (any hold included; the simulator's lead-in not)."""
        played = self.stop - self.start if self.kind == "file" else int(round(self.seconds * FPS))
        return played + self.hold

    def motion(self) -> Motion:
        if self.kind == "file":
            clip = load_file_motion(self.path, self.speed, self.source_fps).slice(self.start, self.stop)
            if self.upper_path:
                upper = load_file_motion(self.upper_path, self.speed, self.source_fps)
                clip = spliced(clip, upper.slice(self.upper_start, self.upper_start + self.stop - self.start))
        else:
            clip = synthesize(self.kind, self.seconds, seed=self.seed, posture=self.posture)
        if self.arm_delay:
            clip = arm_delayed(clip, "l" if self.arm_delay > 0 else "r", abs(self.arm_delay))
        if self.backward:
            clip = played_backward(clip)
        if self.hold:
            clip = held_still(clip, self.hold)
        return clip.mirrored() if self.mirrored else clip

    def _read_marks(self, path: str) -> list[str]:
        """What reading the file does beyond the reader of before 2026-12-03 (module docstring)."""
        if path.lower().endswith(".bvh"):  # the file read once for both
            rate, dropped = bvh_reading(path, self.source_fps, Path(path).stat().st_mtime_ns)
        else:
            rate, dropped = self.source_fps or native_frame_rate(path), 0
        marks = [ANTI_ALIASED] if rate and kernel_width(rate, FPS) > 1.0 else []
        return marks + ([REFERENCE_DROPPED] if dropped else [])

    def key(self, extra: dict) -> str:
        """Content hash of everything that determines the simulated result."""
        # Defaults of fields added later stay out, so earlier sequences keep their keys.
        spec = {
            KEYED_AS.get(k, k): v
            for k, v in asdict(self).items()
            if not (k in LATER_FIELDS and v == LATER_FIELDS[k])
        }
        payload = {"spec": spec, **extra}
        if self.kind == "file":
            payload["file_sha1"] = hashlib.sha1(Path(self.path).read_bytes()).hexdigest()
        if self.upper_path:
            payload["upper_sha1"] = hashlib.sha1(Path(self.upper_path).read_bytes()).hexdigest()
        # since 2026-12-03 a file recorded faster than 30 fps is read low-pass filtered
        # (motion/resample.py) and a conversion's leading T-pose is dropped (motion/reference_frames.py):
        # such a file's sequences simulated before are of other motion; other files keep their keys
        marks = sorted({m for f in (self.path, self.upper_path) if f for m in self._read_marks(f)})
        if marks:
            payload["read"] = marks
        return hashlib.sha256(json.dumps(payload, sort_keys=True, default=str).encode()).hexdigest()[:16]


def load_file_motion(path: str, speed: float = 1.0, source_fps: float | None = None) -> Motion:
    """A motion file at 30 fps, played ``speed`` times faster (resampled; features follow)."""
    return retimed(load_motion(path, source_fps=source_fps), speed)


def on_body(name: str, body_name: str) -> str:
    """The name of a clip's sequence on one of the several bodies it is simulated on (sim/body_plan.py)."""
    return f"{name}__{body_name}"


def in_material(name: str, material: str) -> str:
    """The name of a clip's sequence in one of the several cloths it is simulated in (sim/material_plan)."""
    return f"{name}__{material}"


def clip_name(spec: SequenceSpec) -> str:
    """The name of the clip a sequence plays: its own, less the material's and the body's suffixes of
    a clip simulated in several cloths (:func:`in_material`) or on several bodies (:func:`on_body`)."""
    name = spec.name
    if spec.material is not None:
        name = name.removesuffix(in_material("", spec.material.name))
    return name.removesuffix(on_body("", spec.body_name)) if spec.body_name else name


def sequence_group(spec: SequenceSpec, preset: Preset) -> str:
    """The split group of a sequence: a procedural clip is its own, on every body it stands on, so
    that a preset's held-out clips do not depend on how many bodies each clip has; a file's comes
    from its name (every piece and speed warp of a file shares it)."""
    if spec.kind != "file":
        return clip_name(spec)
    return clip_group(Path(spec.path).stem, preset.split_by, preset.name_pattern)


def safe_name(text: str, empty: str = "clip") -> str:
    """``text`` as a name for a sequence or a body (letters, digits, ``_ . -``; ``empty`` if none is left)."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("_") or empty


def plan_sequences(
    preset: Preset,
    motions: list[str] | None = None,
    seconds: float | None = None,
    source_fps: float | None = None,
) -> list[SequenceSpec]:
    """The preset's procedural clips and motion files, or, when ``motions`` is given, one clip per
    kind named there (repeat a kind for more) and every motion file named there (long files in
    pieces). The preset's speed warps apply to motion files either way; ``source_fps`` is the
    files' own frame rate where they carry none."""
    seconds = float(seconds or preset.seconds)
    counts = _kind_counts(motions) if motions else dict(preset.sequences)
    specs = [
        SequenceSpec(
            f"{kind}_{i:03d}", kind, seed=preset.seed * 1000 + i, seconds=seconds, posture=preset.posture
        )
        for kind, n in counts.items()
        for i in range(n)
    ]
    files = list(file_sources(preset, motions))
    for path in files:
        for speed in (1.0, *preset.speed_warps):
            specs += _file_pieces(path, speed, source_fps)
    taken = sorted(s.path for s in specs if s.name.startswith(AUGMENT_PREFIXES))
    if taken:  # their parts would be the added sequences' parts
        raise InputError(
            taken[0],
            f"a motion file's name may not begin with {' or '.join(AUGMENT_PREFIXES)}, which name the "
            "sequences a build adds; rename the file",
        )
    names = [s.name for s in specs]
    if len(set(names)) != len(names):
        raise HRRError(
            "two motions would get the same sequence name: "
            f"{sorted({n for n in names if names.count(n) > 1})}"
        )
    if not specs:
        raise HRRError("nothing to simulate: the preset lists no sequences and no --motions were given")
    return specs


def _is_file_entry(item: str) -> bool:
    return bool(
        Path(item).suffix or Path(item).exists() or any(c in item for c in "*?[") or item.startswith("mocap:")
    )


def _kind_counts(motions: list[str]) -> dict[str, int]:
    """How many clips of each procedural kind ``--motions`` names (an InputError for an item that is
    neither a kind nor a motion file)."""
    counts: dict[str, int] = {}
    for item in motions:
        if item in KINDS:
            counts[item] = counts.get(item, 0) + 1
        elif not _is_file_entry(item):
            raise InputError(
                item, f"neither a motion kind ({', '.join(KINDS)}) nor a motion file, folder or glob"
            )
    return counts


def _file_pieces(path: str, speed: float, source_fps: float | None) -> list[SequenceSpec]:
    """A motion file as sequences of at most FILE_PIECE_S (a short tail folds into the last)."""
    clip = load_file_motion(path, speed, source_fps)
    if clip.num_frames < MIN_CLIP_FRAMES:
        raise MotionError(
            path,
            f"motion too short to simulate: {clip.num_frames} frames at {clip.fps:g} fps "
            f"(at least {MIN_CLIP_FRAMES})",
        )
    piece = int(FILE_PIECE_S * clip.fps)
    starts = list(range(0, clip.num_frames, piece))
    if len(starts) > 1 and clip.num_frames - starts[-1] < MIN_CLIP_FRAMES:
        starts.pop()
    stem = safe_name(Path(path).stem) + (f"_x{speed:g}" if speed != 1.0 else "")
    specs = []
    for k, start in enumerate(starts):
        stop = starts[k + 1] if k + 1 < len(starts) else clip.num_frames
        suffix = f"_p{k}" if len(starts) > 1 else ""
        specs.append(
            SequenceSpec(
                f"{stem}{suffix}",
                "file",
                path=path,
                start=start,
                stop=stop,
                speed=speed,
                source_fps=source_fps,
            )
        )
    return specs


def build_options(preset: Preset, specs: list[SequenceSpec], motions: list[str] | None = None) -> dict:
    """The preset's keyword arguments for :class:`~hrr_garment.sim.build.BuildSettings`: splits (by
    clip group when it names one), seed, mirroring, each motion file's source (``motions``: the
    files given instead of the preset's) and the provenance recorded in the file."""
    _, left_out = sourced_entries(preset, motions)
    if left_out:
        print(
            f"{preset.name} builds only from commercially usable motion: left out {', '.join(left_out)} "
            "(motion/licences.py)"
        )
    groups = {s.name: sequence_group(s, preset) for s in specs} if preset.split_by else None
    info: dict = {"preset": preset.name, "plan": plan_record(preset)}
    if groups:  # recorded in the file: which groups were held out whole
        info.update(split_by=preset.split_by, groups=groups)
    mirror = mirror_mode(preset.mirror)
    if preset.speed_warps or mirror:
        info["augmentation"] = {"mirror": mirror, "speed_warps": list(preset.speed_warps)}
    also = {}
    for name, fractions in preset.also_hold_out.items():  # only the files whose names have the field
        by = {
            s.name: clip_group(Path(s.path).stem, name, preset.name_pattern)
            for s in specs
            if s.kind == "file"
        }
        by = {n: g for n, g in by.items() if g.startswith(f"{name}=")}
        also[name] = {
            "groups": by,
            "val": float(fractions.get("val", 0.0)),
            "test": float(fractions.get("test", 0.0)),
        }
    if also:
        info["also_hold_out"] = also
    kinds = {s.name: s.kind for s in specs if s.kind != "file"}  # procedural clips: held out in distribution
    splices = SpliceSettings(**preset.splices, name_pattern=preset.name_pattern, seed=preset.seed)
    if splices.adds:
        info.setdefault("augmentation", {"mirror": mirror, "speed_warps": list(preset.speed_warps)})[
            "splices"
        ] = preset.splices
    return {
        "splits": preset.splits,
        "seed": preset.seed,
        "groups": groups,
        "mirror": mirror,
        "info": info,
        "kinds": kinds or None,
        "also_hold_out": also or None,
        "splices": splices if splices.adds else None,
        "file_sources": file_sources(preset, motions),
    }
