"""The library protocol: a game's own clips played again, the way its animation system plays them.

At run time most of a game's motion is its animation library again, and that is what the
retrieval database holds, simulated: the case where retrieving a real simulated window should
beat regressing one. Each *play* takes training clips of the dataset and edits them as a game
would (:mod:`hrr_garment.motion.edit`):

- a *replay*: one clip re-timed by a factor drawn from 0.9-1.1 and entered at a later frame;
- a *transition*: a replay of one clip cross-faded over 0.3-0.5 s into a replay of another.

Every play's ground truth is simulated afresh (the garment settles at the play's first pose, so
it is not the database's own simulation) and scored against its own truth ensemble like any other
sequence. Plays come from a seeded generator: the same dataset, count and seed give the same
plays. They are saved as native motion files (``hrr-animate`` plays them) in a folder named by
their content, so a repeated evaluation finds their simulations cached.

Each play also knows where its frames came from (:class:`PlaySource`: which clip, at which of its
frames), so the database's own simulation of those frames can be played along with it
(:func:`source_simulation`): what retrieval would give if it found the right clip at the right
moment every frame, the protocol's ceiling for any retrieval.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..data.dataset import DatasetError, GarmentDataset
from ..io_utils import atomic_write_text
from ..motion.edit import crossfade, retimed, smoothstep_weights
from ..motion.frame import from_body_frame, to_body_frame
from ..motion.io import save_motion
from ..motion.motion import Motion
from ..motion.resample import resample_linear, resample_times

SPEED_RANGE = (0.9, 1.1)  # re-timing factors a game applies to match a character's speed
BLEND_S = (0.3, 0.5)  # cross-fade lengths between two clips
MIN_ENTRY_S = 0.2  # a play enters its clip at least this far in (never where the database's simulation began)
MIN_CLIP_S = 1.0  # shorter training clips are not played (too little left after the entry)
SOURCE_SIMULATION = "database simulation"  # the reference row: the source clips' own simulation, played along


@dataclass(frozen=True)
class PlaySource:
    """One clip's part of a play: the training clip and, for each of the part's frames, the clip's
    frame it shows (fractional where the play is re-timed)."""

    clip: str
    frames: np.ndarray  # (n,) float64


@dataclass(frozen=True)
class LibraryPlay:
    """One play: a name, how it was made from the training clips, and its motion; ``sources`` the
    clips' parts it plays in order, cross-faded over ``blend`` frames (0: one part)."""

    name: str
    description: str
    motion: Motion
    sources: tuple[PlaySource, ...] = ()
    blend: int = 0


def _entered(
    motion: Motion, rng: np.random.Generator, frames: int, clip: str
) -> tuple[Motion, str, PlaySource]:
    """``motion`` re-timed and entered at a random later frame, at most ``frames`` long."""
    speed = float(rng.uniform(*SPEED_RANGE))
    played = retimed(motion, speed)
    earliest = int(round(MIN_ENTRY_S * motion.fps))
    latest = max(played.num_frames - frames, earliest)  # the last start that still leaves ``frames`` frames
    start = int(rng.integers(earliest, latest + 1))
    stop = min(start + frames, played.num_frames)
    shown = resample_times(motion.num_frames, motion.fps * speed, motion.fps)[
        start:stop
    ]  # as retimed() samples the clip
    return played.slice(start, stop), f"x{speed:.2f} from {start / motion.fps:.2f} s", PlaySource(clip, shown)


def library_plays(
    ds: GarmentDataset, names: list[str], count: int, seconds: float = 4.0, seed: int = 0
) -> list[LibraryPlay]:
    """``count`` plays of the sequences ``names`` (the training split), each about ``seconds``
    long: even-numbered plays are replays, odd-numbered ones transitions."""
    if count < 1:
        raise ValueError(f"count must be at least 1, got {count}")
    motions: dict[str, Motion] = {}

    def motion(name: str) -> Motion:
        if name not in motions:
            motions[name] = ds.sequence(name).motion
        return motions[name]

    fps = ds.fps
    usable = [n for n in names if ds.frames.get(n, 0) >= MIN_CLIP_S * fps]
    if not usable:
        raise DatasetError(
            ds.path, f"no sequence of the model's database is at least {MIN_CLIP_S:g} s long: nothing to play"
        )
    rng = np.random.default_rng(seed)
    frames = int(round(seconds * fps))
    plays = []
    for i in range(count):
        a = usable[int(rng.integers(len(usable)))]
        if i % 2 == 0:
            played, how, source = _entered(motion(a), rng, frames, a)
            plays.append(LibraryPlay(f"play_{i:02d}", f"{a} {how}", played, (source,)))
            continue
        others = [n for n in usable if n != a] or usable  # one clip: a transition into itself, elsewhere
        b = others[int(rng.integers(len(others)))]
        blend = int(round(rng.uniform(*BLEND_S) * fps))
        first, how_a, source_a = _entered(motion(a), rng, frames // 2 + blend, a)
        second, how_b, source_b = _entered(motion(b), rng, frames - frames // 2, b)
        blend = min(blend, first.num_frames, second.num_frames)
        plays.append(
            LibraryPlay(
                f"play_{i:02d}",
                f"{a} {how_a} -> {b} {how_b}, {blend / fps:.2f} s blend",
                crossfade(first, second, blend),
                (source_a, source_b),
                blend,
            )
        )
    return plays


def source_simulation(ds: GarmentDataset, play: LibraryPlay) -> np.ndarray:
    """(T, V, 3) float32 world vertices: the dataset's own simulation of the frames the play shows,
    each in the body frame of its clip's pose, placed on the play's motion (re-timed frames
    interpolated linearly; over a transition's blend the two parts cross-fade with the motion's
    weights)."""
    if not play.sources:
        raise ValueError(f"{play.name} does not record its sources")
    parts = []
    for source in play.sources:
        record = ds.sequence(source.clip)
        parts.append(
            resample_linear(to_body_frame(record.garment.astype(np.float64), record.motion), source.frames)
        )
    local = parts[0]
    if len(parts) == 2:
        first, second, n = parts[0], parts[1], play.blend
        w = smoothstep_weights(n)[:, None, None]
        local = np.concatenate(
            [first[: len(first) - n], (1 - w) * first[len(first) - n :] + w * second[:n], second[n:]]
        )
    if len(local) != play.motion.num_frames:
        raise ValueError(
            f"{play.name}: its sources give {len(local)} frames for {play.motion.num_frames} of motion"
        )
    return from_body_frame(local, play.motion).astype(np.float32)


def plays_digest(plays: list[LibraryPlay]) -> str:
    """A short hash of the plays' names, descriptions and motions."""
    h = hashlib.sha256()
    for p in plays:
        h.update(f"{p.name}\0{p.description}\0".encode())
        h.update(np.ascontiguousarray(p.motion.local_rotations).tobytes())
        h.update(np.ascontiguousarray(p.motion.root_translation).tobytes())
    return h.hexdigest()[:12]


def save_plays(plays: list[LibraryPlay], folder: str | Path) -> list[Path]:
    """Each play as ``folder/NAME.npz`` (a native motion file) and their descriptions in
    ``plays.json``; files already there are kept (their bytes key the simulation cache)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for p in plays:
        path = folder / f"{p.name}.npz"
        if not path.is_file():
            save_motion(
                Motion(
                    p.motion.local_rotations,
                    p.motion.root_translation,
                    p.motion.fps,
                    source=f"library play: {p.description}",
                ),
                path,
            )
        paths.append(path)
    atomic_write_text(folder / "plays.json", json.dumps({p.name: p.description for p in plays}, indent=1))
    return paths
