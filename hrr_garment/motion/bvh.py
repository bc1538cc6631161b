"""BVH reading (writing: :mod:`.bvh_write`).

The reader follows each joint's own CHANNELS line (any rotation order, 3 or 6 channels on any
joint), accepts End Site blocks, blank lines and any whitespace, and checks that the MOTION section
has exactly the announced number of rows with one value per channel. Position channels replace the
joint's OFFSET (the usual convention of exporters that key every joint's translation). The
hierarchy's depth and size, the frame time and the magnitude of every value are bounded
(:mod:`.limits`), so a hostile file gets a one-line error instead of a crash or an absurd motion.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import MotionError
from ..input_files import MAX_BINARY_BYTES, read_input
from .limits import MAX_BVH_DEPTH, MAX_BVH_VALUE, MAX_JOINTS, MIN_SOURCE_FPS, max_frames
from .rotations import euler_to_matrix

_ROT = {"xrotation": "X", "yrotation": "Y", "zrotation": "Z"}
_POS = {"xposition": 0, "yposition": 1, "zposition": 2}


@dataclass
class BvhClip:
    """A parsed BVH file in its own units and naming."""

    names: list[str]
    parents: list[int]
    offsets: np.ndarray  # (J, 3) rest offsets, file units
    end_sites: list[tuple[int, np.ndarray]]  # (parent joint, offset) for each End Site
    local_rotations: np.ndarray  # (T, J, 3, 3)
    local_translations: np.ndarray  # (T, J, 3) file units (OFFSET unless position channels)
    frame_time: float

    @property
    def num_frames(self) -> int:
        return int(self.local_rotations.shape[0])


class _Tokens:
    def __init__(self, path: Path, lines: list[str]):
        self.path = path
        self.items: list[tuple[int, str]] = [
            (n + 1, tok) for n, line in enumerate(lines) for tok in line.split()
        ]
        self.pos = 0

    def next(self, what: str) -> tuple[int, str]:
        if self.pos >= len(self.items):
            raise MotionError(
                self.path, f"unexpected end of file while reading {what} (truncated HIERARCHY?)"
            )
        item = self.items[self.pos]
        self.pos += 1
        return item

    def expect(self, word: str) -> int:
        line, tok = self.next(repr(word))
        if tok.upper() != word.upper():
            raise MotionError(self.path, f"line {line}: expected {word!r}, found {tok!r}")
        return line

    def floats(self, n: int, what: str) -> np.ndarray:
        vals = []
        for _ in range(n):
            line, tok = self.next(what)
            try:
                vals.append(float(tok))
            except ValueError:
                raise MotionError(
                    self.path, f"line {line}: expected a number in {what}, found {tok!r}"
                ) from None
        out = np.array(vals, dtype=np.float64)
        if not (np.abs(out) <= MAX_BVH_VALUE).all():
            raise MotionError(
                self.path,
                f"line {line}: {what} has {out.tolist()}; values must be finite and within "
                f"+-{MAX_BVH_VALUE:g} file units",
            )
        return out


@dataclass
class _Hierarchy:
    """The HIERARCHY section as read: joints in file order, their CHANNELS lines and End Sites."""

    names: list[str]
    parents: list[int]
    offsets: list[np.ndarray]
    channels: list[list[str]]
    end_sites: list[tuple[int, np.ndarray]]


def _read_channels(tokens: _Tokens, name: str) -> list[str]:
    """A joint's CHANNELS line: 3 or 6 channels, the three rotations once each, optionally the
    three positions."""
    path = tokens.path
    tokens.expect("CHANNELS")
    cline, count_tok = tokens.next(f"channel count of {name}")
    if count_tok not in ("3", "6"):
        raise MotionError(
            path, f"line {cline}: joint {name!r} has {count_tok} channels; 3 or 6 are supported"
        )
    chans = [tokens.next(f"channels of {name}")[1].lower() for _ in range(int(count_tok))]
    unknown = [c for c in chans if c not in _ROT and c not in _POS]
    rot = [c for c in chans if c in _ROT]
    pos = [c for c in chans if c in _POS]
    if unknown or len(set(rot)) != 3 or len(rot) != 3 or (pos and len(set(pos)) != 3):
        raise MotionError(
            path,
            f"line {cline}: joint {name!r} has channels {chans}; need the three rotations "
            "X, Y and Z once each (and optionally the three positions)",
        )
    return chans


def _parse_joint(tokens: _Tokens, tree: _Hierarchy, parent: int, depth: int) -> None:
    """One JOINT (or the ROOT) block and, recursively, its children, appended to ``tree``."""
    path = tokens.path
    line, name = tokens.next("joint name")
    if depth > MAX_BVH_DEPTH or len(tree.names) >= MAX_JOINTS:
        raise MotionError(
            path,
            f"line {line}: joint {name!r} is "
            f"{'nested ' + str(depth) + ' deep' if depth > MAX_BVH_DEPTH else 'one joint too many'}; at most "
            f"{MAX_BVH_DEPTH} levels and {MAX_JOINTS} joints are read",
        )
    index = len(tree.names)
    tree.names.append(name)
    tree.parents.append(parent)
    tokens.expect("{")
    tokens.expect("OFFSET")
    tree.offsets.append(tokens.floats(3, f"OFFSET of {name}"))
    tree.channels.append(_read_channels(tokens, name))
    while True:
        kline, kw = tokens.next(f"children of {name}")
        if kw == "}":
            return
        if kw.upper() == "JOINT":
            _parse_joint(tokens, tree, index, depth + 1)
        elif kw.upper() == "END":
            tokens.expect("Site")
            tokens.expect("{")
            tokens.expect("OFFSET")
            tree.end_sites.append((index, tokens.floats(3, f"End Site of {name}")))
            tokens.expect("}")
        else:
            raise MotionError(path, f"line {kline}: unexpected {kw!r} inside joint {name!r}")


def _parse_hierarchy(path: Path, lines: list[str]) -> _Hierarchy:
    """The HIERARCHY section (``lines`` up to the MOTION line): one ROOT and nothing after it."""
    tokens = _Tokens(path, lines)
    tokens.expect("HIERARCHY")
    tree = _Hierarchy([], [], [], [], [])
    tokens.expect("ROOT")
    _parse_joint(tokens, tree, -1, 0)
    if tokens.pos != len(tokens.items):
        line, tok = tokens.items[tokens.pos]
        raise MotionError(
            path, f"line {line}: unexpected {tok!r} after the hierarchy (only one ROOT is supported)"
        )
    return tree


def _motion_header(path: Path, body: list[tuple[int, str]]) -> tuple[int, float]:
    """The MOTION section's frame count and frame time (``body``: its non-blank lines, numbered)."""
    if (
        len(body) < 2
        or not body[0][1].strip().lower().startswith("frames:")
        or not body[1][1].strip().lower().startswith("frame time:")
    ):
        raise MotionError(path, "MOTION section must start with 'Frames:' and 'Frame Time:' lines")
    try:
        n_frames = int(body[0][1].split(":", 1)[1])
        frame_time = float(body[1][1].split(":", 1)[1])
    except ValueError:
        raise MotionError(path, f"line {body[0][0]}: cannot read the frame count or frame time") from None
    if not (np.isfinite(frame_time) and 0 < frame_time <= 1.0 / MIN_SOURCE_FPS):
        raise MotionError(
            path,
            f"line {body[1][0]}: frame time must be a positive number of seconds up to "
            f"{1.0 / MIN_SOURCE_FPS:g}, got {frame_time:g} (give the capture rate with --fps)",
        )
    if n_frames > max_frames():
        raise MotionError(
            path,
            f"line {body[0][0]}: {n_frames:,} frames, over the limit of {max_frames():,} "
            "(set HRR_MAX_FRAMES to raise it)",
        )
    return n_frames, frame_time


def _frame_rows(path: Path, rows: list[tuple[int, str]], n_frames: int, n_chan: int) -> np.ndarray:
    """The (T, channels) values of the frame rows, checked: as many rows as announced, one value
    per channel, every value a finite number within the bounds."""
    if len(rows) < n_frames:
        raise MotionError(
            path, f"truncated: header announces {n_frames} frames but only {len(rows)} frame rows follow"
        )
    if len(rows) > n_frames:
        raise MotionError(path, f"header announces {n_frames} frames but {len(rows)} frame rows follow")
    if n_frames == 0:
        raise MotionError(path, "the motion has no frames")
    split = [r.split() for _, r in rows]
    for (line_no, _), vals in zip(rows, split):
        if len(vals) != n_chan:
            raise MotionError(
                path, f"line {line_no}: expected {n_chan} values (one per channel), found {len(vals)}"
            )
    try:
        data = np.array(split, dtype=np.float64)
    except ValueError:
        raise MotionError(path, "frame rows contain values that are not numbers") from None
    if not np.isfinite(data).all():
        bad = int(np.argmax(~np.isfinite(data).all(1)))
        raise MotionError(path, f"non-finite value (NaN or inf) in frame {bad} (line {rows[bad][0]})")
    if not (np.abs(data) <= MAX_BVH_VALUE).all():
        bad = int(np.argmax((np.abs(data) > MAX_BVH_VALUE).any(1)))
        raise MotionError(
            path,
            f"frame {bad} (line {rows[bad][0]}) has a value beyond +-{MAX_BVH_VALUE:g} "
            "(file units or degrees): a corrupt row",
        )
    return data


def _local_transforms(
    data: np.ndarray, channels: list[list[str]], offsets: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Each joint's local rotations (T, J, 3, 3) and translations (T, J, 3) from the frame values:
    its rotation channels in its own order, its position channels where it has them, else its OFFSET."""
    n_frames, n_joints = len(data), len(channels)
    local_rot = np.empty((n_frames, n_joints, 3, 3))
    local_trans = np.broadcast_to(offsets, (n_frames, n_joints, 3)).copy()
    col = 0
    for j, chans in enumerate(channels):
        cols = {c: col + k for k, c in enumerate(chans)}
        order = "".join(_ROT[c] for c in chans if c in _ROT)
        angles = data[:, [cols[c] for c in chans if c in _ROT]]
        local_rot[:, j] = euler_to_matrix(angles, order)
        if "xposition" in cols:
            local_trans[:, j] = data[:, [cols["xposition"], cols["yposition"], cols["zposition"]]]
        col += len(chans)
    return local_rot, local_trans


def read_bvh(path: str | Path) -> BvhClip:
    """Parse a BVH file into its hierarchy and channels (no retargeting)."""
    path = Path(path)
    text = read_input(path, limit=MAX_BINARY_BYTES, what="a BVH file").decode("utf-8", errors="replace")
    lines = text.splitlines()
    motion_line = next((i for i, line in enumerate(lines) if line.strip().upper().startswith("MOTION")), None)
    if motion_line is None:
        raise MotionError(path, "no MOTION section (not a BVH file, or truncated)")
    tree = _parse_hierarchy(path, lines[:motion_line])
    body = [
        (n, line) for n, line in enumerate(lines[motion_line + 1 :], start=motion_line + 2) if line.strip()
    ]
    n_frames, frame_time = _motion_header(path, body)
    data = _frame_rows(path, body[2:], n_frames, sum(len(c) for c in tree.channels))
    offsets_arr = np.array(tree.offsets)
    local_rot, local_trans = _local_transforms(data, tree.channels, offsets_arr)
    return BvhClip(tree.names, tree.parents, offsets_arr, tree.end_sites, local_rot, local_trans, frame_time)
