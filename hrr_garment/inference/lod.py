"""Level of detail for a crowd's characters (``crowd.push(..., lod=...)``): what each character's
step runs, chosen per character per frame, and the cross-fade that hides a change.

    crowd.push(rotations, roots, keys, lod=[0, 0, 1, 4])   # near, near, mid, far

- level 0: the crowd's own decoder (its run settings' ``decoder``), the window step every frame;
- level 1: the fast (subspace) decoder every frame, where the model has one;
- level k >= 2: the fast decoder, and the window step (motion encoder, gate, code-space decoder)
  only every k-th of the character's frames; in between its latent is held. The features and the
  motion memory still advance every frame, so the window is current when the step runs again.

No pop: a change of decoder is cross-faded in the body frame: on the frame of the change both
decoders decode the character's latent, and their difference is added to the new decoder's output,
fading to nothing over ``fade`` frames (smoothstep), so a frame moves at most about 1.5 / ``fade``
of the difference more than the cloth itself moves. A held latent goes through the character's
inertialization like a change of source, so the latent that arrives when the step runs again is
blended in, not jumped to (:class:`~.blending.Inertializer`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import blending
from .blending import causal_source

FADE_FRAMES = 8  # frames a decoder change fades over


def levels(lod, count: int) -> np.ndarray:
    """``lod`` (None, an int for all, or one per character) as (count,) non-negative ints; a
    ValueError naming what is wrong otherwise."""
    if lod is None:
        return np.zeros(count, np.int64)
    values = np.asarray(lod)
    if values.ndim == 0:
        values = np.full(count, values)
    if values.shape != (count,) or not np.issubdtype(values.dtype, np.integer) or (values < 0).any():
        raise ValueError(
            f"lod takes a level >= 0 per character (or one for all), got {lod!r} for {count} characters"
        )
    return values.astype(np.int64)


def decoder_of(level: int, run_decoder: str, has_fast: bool) -> str:
    """The decoder a character at ``level`` runs: the crowd's at level 0, the fast one above (where there is
    one)."""
    return "fast" if level >= 1 and has_fast else run_decoder


def steps_now(level: int, frame: int) -> bool:
    """Whether a character at ``level`` runs the window step on its ``frame``-th frame (its first always)."""
    return level < 2 or frame % level == 0


@dataclass
class DecoderFade:
    """What is left of a decoder change: the old decoder's output minus the new one's on the frame
    of the change, and the frames the fade has run."""

    difference: np.ndarray  # (V, 3)
    frame: int = 0
    frames: int = FADE_FRAMES

    def weight(self) -> float:
        """The difference's weight this frame: 1 at the change, down to 0 (smoothstep)."""
        x = min(self.frame / self.frames, 1.0)
        return 1.0 - x * x * (3.0 - 2.0 * x)

    def apply(self, local: np.ndarray) -> np.ndarray:
        """This frame's body-frame vertices with the fading difference added; advances the fade."""
        out = local + np.float32(self.weight()) * self.difference
        self.frame += 1
        return out

    @property
    def done(self) -> bool:
        return self.frame > self.frames


@dataclass
class LodState:
    """A character's level-of-detail state: its last window step's latent and match (held between
    steps), the decoder it last ran and the fade of a change of decoder."""

    latent: np.ndarray | None = None  # (nodes, C) the last window step's latent, before inertialization
    match: np.ndarray | None = None  # (2,) that step's database match (sequence, start) or -1
    # (nodes, C) that step's share that swings as the regression (gate.WindowChoice.regression_part, or None)
    regression: np.ndarray | None = None
    # (nodes, C) that step's regression, which the mode's additions depart from (gate.WindowChoice.regression)
    base: np.ndarray | None = None
    since: int = 0  # the character's frame of that step
    decoder: str | None = None
    fade: DecoderFade | None = None


def crowd_latents(chars: list, lv: np.ndarray, choose, inertialize_rows) -> np.ndarray:
    """The window step for the characters whose level runs it this frame, their held latents for
    the others: -> (N, nodes, C) inertialized latents (each character's ``lod`` holds its match).
    ``choose``: the rows of the characters stepping (None: all) -> their windows'
    :class:`~.gate.WindowChoice`; ``inertialize_rows``: (targets (N, nodes, C) float64, their
    source ids, continuous parts (N, nodes, C) or None, which rows have one (N,)) -> the characters'
    inertialized latents, all in one call (:meth:`~.blending.Inertializer.step_rows`)."""
    stepping = np.array(
        [steps_now(int(level), c.frames) or c.lod.latent is None for level, c in zip(lv, chars)]
    )
    rows = np.flatnonzero(stepping)
    choice = choose(None if stepping.all() else rows) if rows.size else None
    shape = choice.latents.shape[2:] if choice is not None else chars[0].lod.latent.shape
    targets = np.empty((len(chars), *shape), np.float64)
    sources: list = [None] * len(chars)
    continuous, split = None, np.zeros(len(chars), bool)
    if choice is not None:
        targets[rows] = choice.latents[:, -1]
        for j, i in enumerate(rows):
            c = chars[i]
            c.lod.latent, c.lod.match, c.lod.since = choice.latents[j, -1], choice.match[j], c.frames
            c.lod.regression = None if choice.regression_part is None else choice.regression_part[j, -1]
            c.lod.base = None if choice.regression is None else choice.regression[j, -1]
            sources[i] = causal_source(choice.follows_match[j], choice.match[j], c.frames)
        if choice.continuous is not None and blending.DEPARTURE_ONLY:  # else the whole latent inertialized
            continuous = np.zeros_like(targets)
            continuous[rows], split[rows] = choice.continuous[:, -1], True
    for i in np.flatnonzero(
        ~stepping
    ):  # held: a source of its own (all of it), so the next step's latent is blended in
        c = chars[i]
        targets[i], sources[i] = c.lod.latent, ("held", c.lod.since)
    return inertialize_rows(targets, sources, continuous, split).astype(np.float32)


def _decoded(latents: np.ndarray, names: list[str], decoders: dict) -> np.ndarray:
    """(N, V, 3) body-frame vertices: row i of ``latents`` (N, nodes, C) through the decoder
    ``names[i]`` (a key of ``decoders``), the rows of one decoder in one batch."""
    import torch

    kinds = list(dict.fromkeys(names))
    if len(kinds) == 1:  # one decoder for all (every crowd without levels of detail): one batch, no copies
        with torch.no_grad():
            return decoders[kinds[0]](torch.from_numpy(latents)).numpy()
    out = None
    for name in kinds:
        rows = [i for i, n in enumerate(names) if n == name]
        with torch.no_grad():
            decoded = decoders[name](torch.from_numpy(np.ascontiguousarray(latents[rows]))).numpy()
        out = np.empty((len(latents), *decoded.shape[1:]), np.float32) if out is None else out
        out[rows] = decoded
    return out


def crowd_bases(chars: list, names: list[str], decoders: dict) -> np.ndarray | None:
    """(N, V, 3) body-frame vertices of the characters' regressions (their ``lod.base``), each through
    its decoder ``names[i]`` (no fade: the push-out's take-back reads them, :mod:`.take_back`), or None
    where a character has none (a mode that adds nothing to its regression)."""
    if any(c.lod.base is None for c in chars):
        return None
    return _decoded(np.stack([c.lod.base for c in chars]).astype(np.float32), names, decoders)


def crowd_decode(chars: list, latents: np.ndarray, names: list[str], decoders: dict) -> np.ndarray:
    """(N, V, 3) body-frame vertices: each character through the decoder ``names[i]`` (a key of
    ``decoders``), those of one decoder in one batch; a character whose decoder changed since its
    last frame gets the change's difference cross-faded (:class:`DecoderFade`)."""
    import torch

    out = _decoded(latents, names, decoders)
    for i, c in enumerate(chars):
        state = c.lod
        if state.decoder is not None and state.decoder != names[i]:
            with torch.no_grad():
                before = decoders[state.decoder](torch.from_numpy(latents[i : i + 1])).numpy()[0]
            previous = state.fade.apply(before) if state.fade is not None and not state.fade.done else before
            state.fade = DecoderFade(previous - out[i])
        state.decoder = names[i]
        if state.fade is not None:
            out[i] = state.fade.apply(out[i])
            if state.fade.done:
                state.fade = None
    return out
