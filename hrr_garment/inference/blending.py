"""From per-window latents to per-frame latents.

Offline, each frame's latent is the weighted mean of the windows that cover it, with weights that
peak at window centres (sin^2), so a change of source between windows is a cross-fade, continuous
in position and velocity. Causal, frame t takes the last frame of the window ending at t, and a
change of source (mode, or retrieved clip) is removed by inertialization: the jump between the old
and the new source (in position and velocity) becomes an offset that decays to zero as a
critically damped spring over about ``blend`` frames.
"""

from __future__ import annotations

import numpy as np

from .gate import WindowChoice


def window_weights(size: int) -> np.ndarray:
    """Blend weight of each position in a window: sin^2, highest at the centre, never zero."""
    return np.sin(np.pi * (np.arange(size) + 0.5) / size) ** 2


def blend_windows(latents: np.ndarray, frames: int) -> np.ndarray:
    """Per-frame weighted mean of overlapping windows: latents (N, W, ...) with window i covering
    frames i .. i + W - 1 -> (frames, ...)."""
    n, w = latents.shape[:2]
    weights = window_weights(w)
    total = np.zeros((frames, *latents.shape[2:]), np.float64)
    norm = np.zeros(frames)
    for k in range(w):
        total[k : k + n] += weights[k] * latents[:, k]
        norm[k : k + n] += weights[k]
    return (total / norm.reshape(-1, *([1] * (latents.ndim - 2)))).astype(np.float32)


_STATE = ("offset", "offset_vel", "prev_target", "prev_target_vel", "prev_part", "prev_part_vel")


class Inertializer:
    """Removes jumps when the latent source switches: the output is the current source plus an
    offset that absorbs each switch's jump in position and velocity (the old source's value and
    velocity, extrapolated one frame, minus the new one's) and decays to zero as a critically damped
    spring with a half-life of ``frames / 3`` frames (1 % of a jump is left after about ``frames``
    + 4 frames). Offsets of switches that come before the last one has decayed add up and decay
    together, so a source that changes every frame (retrieval picking another clip each window) is
    smoothed, not extrapolated: the output stays within a few jumps of the sources. (A quintic that
    restarted from the output's own velocity at every switch ran away on such streams: 720 mm on
    causal retrieval of real clips.)

    A target with a ``continuous`` part (one source whatever the match: the regression under a
    residual) jumps only by the rest at a switch between two such targets; the continuous part is
    followed as it is (extrapolated at every change of match, it lagged: causal PVE 33.8 against the
    regression's 31.7 mm). Between a target with and one without, the whole jumps.

    It keeps ``paths`` such latent paths, one row each (a crowd's characters: :meth:`add_path`,
    :meth:`remove_path`), stepped together by :meth:`step_rows` in one array operation per term:
    stepped one numpy call per character, they took 0.7 ms of a 64-character step. Each row's
    arithmetic is elementwise, so a path gives the same bits stepped alone or in a crowd."""

    def __init__(self, frames: int = 6, paths: int = 1):
        self.frames = frames
        # one frame of a critically damped spring (exact) with half-life frames / 3: fixed per stream
        self._damping = 2.0 * np.log(2.0) / max(frames / 3.0, 1e-6)
        self._decay = float(np.exp(-self._damping))
        self._paths = paths
        self._state: dict[str, np.ndarray] | None = (
            None  # each of _STATE (paths, ...) float64, made at the first step
        )
        self._split = np.zeros(paths, bool)  # whether its previous target had a continuous part
        self._sources: list = [None] * paths  # each path's last source (None: no previous target)
        self._free: list[int] = []  # rows of removed paths, given to the next added

    def add_path(self) -> int:
        """A new path's row (from its start: no offset, no previous target)."""
        if self._free:
            return self._free.pop()
        self._paths += 1
        self._split = np.append(self._split, False)
        self._sources.append(None)
        if self._state is not None:
            self._state = {k: np.concatenate([v, np.zeros_like(v[:1])]) for k, v in self._state.items()}
        return self._paths - 1

    def remove_path(self, row: int) -> None:
        """Forget the path in ``row``; its row goes to the next :meth:`add_path`."""
        self._sources[row] = None
        if self._state is not None:
            for v in self._state.values():
                v[row] = 0.0
        self._free.append(row)

    def step(self, target: np.ndarray, source: tuple, continuous: np.ndarray | None = None) -> np.ndarray:
        """target: this frame's latent from ``source`` (a hashable id of where it came from);
        ``continuous``: its part that does not change with the source (see the class docstring).
        The path in row 0."""
        rows = np.zeros(1, np.int64) if self._paths > 1 else None
        return self.step_rows(
            target[None], [source], None if continuous is None else continuous[None], rows=rows
        )[0]

    def step_rows(
        self,
        targets: np.ndarray,
        sources: list,
        continuous: np.ndarray | None = None,
        split: np.ndarray | None = None,
        rows: np.ndarray | None = None,
    ) -> np.ndarray:
        """:meth:`step` of many paths: ``targets`` (R, ...), one source each; ``continuous`` (R, ...)
        and ``split`` (R,) which rows have one (default: all where ``continuous`` is given);
        ``rows``: the paths stepped (None: all, in order)."""
        targets = np.array(targets, np.float64)  # a copy: kept as the previous target, written in place later
        count = len(targets)
        if rows is not None and len(rows) == self._paths and np.array_equal(rows, np.arange(self._paths)):
            rows = None  # every path, in order: the arrays themselves, no gather
        if rows is None and count != self._paths:
            raise ValueError(f"{count} targets for {self._paths} paths (pass the rows stepped)")
        split = np.full(count, continuous is not None) if split is None else np.asarray(split, bool)
        if self._state is None:
            self._state = {k: np.zeros((self._paths, *targets.shape[1:])) for k in _STATE}
        every = rows is None
        idx = slice(None) if every else rows
        state = self._state if every else {k: v[idx] for k, v in self._state.items()}
        was_split = self._split[idx]
        old_sources = self._sources if every else [self._sources[i] for i in rows]
        started = np.array([o is not None for o in old_sources], bool)
        part = (
            targets if continuous is None else np.where(_rows(split, targets), targets - continuous, targets)
        )
        same = started & (split == was_split) & np.array([s == o for s, o in zip(sources, old_sources)], bool)
        offset, offset_vel = state["offset"], state["offset_vel"]
        switch = started & ~same
        if switch.any():
            # the old source one frame on (moving as it last did) against the new one (velocity
            # unknown: 0); between a target with a continuous part and one without, the whole
            keep = _rows(switch & (split == was_split), targets)
            whole = _rows(switch & (split != was_split), targets)
            before = np.where(keep, state["prev_part"], state["prev_target"])
            velocity = np.where(keep, state["prev_part_vel"], state["prev_target_vel"])
            now = np.where(keep, part, targets)
            moved = keep | whole
            offset = np.where(moved, offset + before + velocity - now, offset)
            offset_vel = np.where(moved, offset_vel + velocity, offset_vel)
        damping, decay = self._damping, self._decay
        j1 = offset_vel + offset * damping
        offset, offset_vel = decay * (offset + j1), decay * (offset_vel - j1 * damping)
        continuing = _rows(same, targets)
        new = {
            "offset": offset,
            "offset_vel": offset_vel,
            "prev_target": targets,
            "prev_part": part if continuous is not None else targets.copy(),  # rows of its own, written apart
            "prev_target_vel": np.where(continuing, targets - state["prev_target"], 0.0),
            "prev_part_vel": np.where(continuing, part - state["prev_part"], 0.0),
        }
        if every:
            self._state = new
            self._split, self._sources = split.copy(), list(sources)
        else:
            for k, v in new.items():
                self._state[k][rows] = v
            self._split[rows] = split
            for i, s in zip(rows, sources):
                self._sources[i] = s
        return targets + offset


def _rows(mask: np.ndarray, like: np.ndarray) -> np.ndarray:
    """A per-row mask shaped to broadcast against ``like`` (rows first)."""
    return mask.reshape(-1, *([1] * (like.ndim - 1)))


def source_id(retrieved: bool, source: np.ndarray) -> tuple:
    """Consecutive causal windows from one retrieved clip advance by one frame each: same id."""
    return ("regression",) if not retrieved else ("retrieval", int(source[0]), int(source[1]))


# causal paths inertialize only a residual's departure at a change of match (decision 0024); False:
# the whole latent, as hrr_garment did before 2026-11-27 (tests reproduce its files with it)
DEPARTURE_ONLY = True


def causal_source(retrieved: bool, source: np.ndarray, frame: int) -> tuple:
    """The source id of a causal window ending at clip frame ``frame``: a retrieved window's
    ``source`` (database sequence, start) is taken back to that clip's frame 0 first, so
    consecutive windows of one clip keep one id."""
    return source_id(bool(retrieved), source - np.array([0, frame]) if retrieved else source)


def inertialize(
    inert: Inertializer,
    latent: np.ndarray,
    retrieved: bool,
    source: np.ndarray,
    frame: int,
    continuous: np.ndarray | None = None,
) -> np.ndarray:
    """One causal frame of one latent path: ``latent`` (nodes, C), the last frame of the window
    ending at clip frame ``frame`` from ``source`` (:func:`causal_source`). ``continuous``: the part
    of ``latent`` that does not change with the source (the regression under a residual,
    :attr:`~.gate.WindowChoice.continuous`): followed as it is, only the rest inertialized
    (:class:`Inertializer`)."""
    return inert.step(
        latent.astype(np.float64),
        causal_source(retrieved, source, frame),
        continuous=None if continuous is None or not DEPARTURE_ONLY else continuous.astype(np.float64),
    )


def latent_sources(choice: WindowChoice) -> tuple[np.ndarray, np.ndarray]:
    """The latents a causal path inertializes and whether each window's change with its match
    (:attr:`~.gate.WindowChoice.follows_match`)."""
    return choice.latents, choice.follows_match


def causal_latents(choice: WindowChoice, blend: int = 6) -> np.ndarray:
    """Frame t's latent = the last frame of the window ending at t, made continuous across source
    changes by :class:`Inertializer`. ``choice`` has one window per frame."""
    latents, retrieved = latent_sources(choice)
    inert = Inertializer(blend)
    out = np.empty((len(latents), *latents.shape[2:]), np.float32)
    for t in range(len(out)):
        out[t] = inertialize(
            inert,
            latents[t, -1],
            retrieved[t],
            choice.match[t],
            t,
            continuous=None if choice.continuous is None else choice.continuous[t, -1],
        )
    return out
