"""The detail mode's fold track: which simulated frames lend their folds to each output frame.

Every window proposes its best match's frame for the output frame (offline the centred window's,
causal the last one's). Taking each frame's proposal as it comes would switch folds almost every
frame (the matches of neighbouring windows come from different clips), and a blend of the
proposals averages the folds away. The track does what motion matching does: a playhead in one
database sequence that plays forward one frame per frame while the proposals agree with it, jumps to
the current proposal when they have disagreed for ``hold`` frames (or its sequence ends), and
cross-fades the old playhead's folds out over ``fade`` frames after a jump. The same step runs
offline, causal and streaming, so a stream equals the causal track.

*Resting.* Where the same window keeps matching (a body standing still), every frame proposes the
same simulated frame. A playhead that played on from it would disagree after ``slack`` frames and jump
back after ``hold`` more: a loop of a dozen frames of another simulation's moving folds, for as long
as the body stands (the clocked stops model's hem moved at 0.17 m/s 12 s into a stop, the truth's at
0.01). Once the proposal has stayed the same for ``rest`` frames the playhead therefore stops
advancing. At the defaults it has then played past the slack, so it jumps back to the proposal once
(with the fade) and rests there, and the folds stand still with the body. A rest of ``slack + 1``
would rest without that jump, but it also froze the folds of a tiny model's walk, whose matches
repeat for a few frames while the body moves.

*Following in time.* The playhead's folds are another simulation's, so their motion is not the
truth's: every millimetre of their acceleration adds to the output's jitter (detail on the
regression, 16 held-out clips: 1.11 x the truths' jitter against the regression's 0.95). The folds
a frame gets therefore follow the playhead's (:func:`follow_folds`): an exponential smoothing in
time that moves :data:`FOLD_FOLLOW` of the way to this frame's folds, scaled back to their
curvature (the smoothing of a moving fold flattens it; the scale is the ratio of the 1-ring
Laplacian's size, the folds' own over the followed, itself followed so that it adds no jitter).
Causal and one frame at a time, so it runs alike offline, causal and streaming. On 12 validation
clips (offline, no push-out, against each clip's simulation) it took the jitter from 7.06 to 6.38
mm (the regression's 6.11) with 0.98 of the bending energy and the same PVE and hem swing
(docs/decisions/0024-folds-followed-in-time.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix

from ..garment.smoothing import high_frequencies

FOLD_HOLD = 8  # frames the proposals may disagree with the playhead before it jumps
FOLD_FADE = 6  # frames over which the folds of the frame jumped from fade out
FOLD_SLACK = 3  # a proposal this many frames or fewer from the playhead, in its sequence, agrees
FOLD_REST = 8  # frames one proposal must repeat before the playhead rests on it (module docstring)
# the share of the way the followed folds move to this frame's each frame (1: no smoothing); on
# validation 0.4 / 0.5 / 0.6 left 6.38 / 6.47 / 6.56 mm of jitter at 0.980 / 0.983 / 0.985 of the
# folds' bending energy (decision 0024)
FOLD_FOLLOW = 0.4


@dataclass
class FoldTrack:
    """One animation's playhead; :meth:`step` once per output frame."""

    offsets: (
        np.ndarray
    )  # (S + 1,) the fold store's: sequence s's frames are rows offsets[s] .. offsets[s + 1] - 1
    hold: int = FOLD_HOLD
    fade: int = FOLD_FADE
    slack: int = FOLD_SLACK
    rest: int = FOLD_REST
    sequence: int = -1
    frame: int = 0
    disagreed: int = 0  # frames since a proposal last agreed (or since the jump)
    old_sequence: int = -1
    old_frame: int = 0
    fading: int = 0  # frames of the old playhead's fade left
    last: tuple[int, int] = (-1, -1)  # the last proposal
    repeated: int = 0  # frames it has been the same (``rest`` or more: the playhead rests)

    def __post_init__(self) -> None:
        self.lengths = np.diff(self.offsets)

    def step(self, sequence: int, frame: int) -> tuple[np.ndarray, np.ndarray]:
        """This frame's proposal (database sequence, frame) -> the fold store rows (2,) of the
        playhead and of the one fading out, and their weights (2,) (0 when none; they sum to 1)."""
        sequence, frame = int(sequence), int(frame)
        self.repeated = self.repeated + 1 if (sequence, frame) == self.last else 0
        self.last = (sequence, frame)
        if self.sequence < 0:
            self.sequence, self.frame = sequence, frame
        else:
            self.frame += 0 if self.repeated >= self.rest else 1  # resting (module docstring)
            self.old_frame = (
                min(self.old_frame + 1, int(self.lengths[self.old_sequence]) - 1) if self.fading else 0
            )
            agrees = sequence == self.sequence and abs(frame - self.frame) <= self.slack
            self.disagreed = 0 if agrees else self.disagreed + 1
            if self.frame >= self.lengths[self.sequence] or self.disagreed >= self.hold:
                self.old_sequence, self.old_frame = (
                    self.sequence,
                    min(self.frame, int(self.lengths[self.sequence]) - 1),
                )
                self.sequence, self.frame, self.disagreed, self.fading = sequence, frame, 0, self.fade
        old = self.fading / (self.fade + 1.0)
        here = self.offsets[self.sequence] + self.frame
        rows = np.array(
            [here, self.offsets[self.old_sequence] + self.old_frame if self.fading else here], np.int64
        )
        self.fading = max(self.fading - 1, 0)
        return rows, np.array([1.0 - old, old])


def offline_proposals(source: np.ndarray, frames: int, window: int) -> np.ndarray:
    """Offline: frame t's proposal is its frame in the match of the window centred on it among the
    windows the clip fills (:func:`centred_windows`; window i covers frames i - W + 1 .. i:
    :func:`~hrr_garment.motion.windows.covering_windows`). ``source`` (frames + W - 1, 2) (database
    sequence, start) -> (frames, 2)."""
    if len(source) != frames + window - 1:
        raise ValueError(
            f"offline proposals take the matches of the {frames + window - 1} windows that hold a frame "
            f"of a {frames}-frame clip (covering_windows), got {len(source)}"
        )
    i = centred_windows(frames, window)
    return np.stack([source[i, 0], source[i, 1] + np.arange(frames) - (i - window + 1)], 1)


def centred_windows(frames: int, window: int) -> np.ndarray:
    """(frames,) each frame's window among a clip's covering windows (window i holding frames
    i - W + 1 .. i): the one centred on it, or near an end the clip's first or last window of its own
    frames alone (one past its ends holds repeated frames: its match is no sequence to follow, and
    its entropy no window of the clip's)."""
    own = np.clip(np.arange(frames) - window // 2, 0, max(frames - window, 0))  # first frame held
    return own + window - 1


def causal_proposals(source: np.ndarray, window: int) -> np.ndarray:
    """Causal: frame t's proposal is the last frame of the match of the window ending at t."""
    return np.stack([source[:, 0], source[:, 1] + window - 1], 1)


def track_folds(proposals: np.ndarray, offsets: np.ndarray, **settings: int) -> tuple[np.ndarray, np.ndarray]:
    """(T, 2) proposals -> the fold store rows (T, 2) and weights (T, 2) of a :class:`FoldTrack`
    over them (``offsets``: the store's; ``settings``: its hold, fade, slack or rest, for analysis)."""
    track = FoldTrack(offsets, **settings)
    steps = [track.step(sequence, frame) for sequence, frame in proposals]
    return np.array([r for r, _ in steps], np.int64).reshape(-1, 2), np.array([w for _, w in steps]).reshape(
        -1, 2
    )


@dataclass
class FollowedFolds:
    """One animation's folds as followed so far (:func:`follow_folds`)."""

    folds: np.ndarray  # (V, 3) float64: the smoothed folds, before their scale
    laplacian: np.ndarray  # (V, 3) float64: their 1-ring Laplacian (the smoothing is linear: followed alike)
    scale: float  # the followed curvature ratio


def _laplacian(folds: np.ndarray, mean: csr_matrix) -> np.ndarray:
    """(N, V, 3) -> (N, V, 3): each vertex less the mean of its 1-ring."""
    return high_frequencies(folds, mean, 1)


def _size(laplacian: np.ndarray) -> np.ndarray:
    """(N, V, 3) -> (N,): the root mean square of a Laplacian's vectors (the folds' curvature)."""
    return np.sqrt(np.einsum("nvc,nvc->n", laplacian, laplacian) / laplacian.shape[1])


def follow_folds(
    folds: np.ndarray, states: list[FollowedFolds | None], mean: csr_matrix, follow: float | None = None
) -> np.ndarray:
    """One frame of N animations: their fold terms (N, V, 3) -> as they are shown (N, V, 3) float64;
    ``states`` (N,) their :class:`FollowedFolds`, updated in place (None: the animation's first
    frame, shown as it is). ``mean``: the mesh's 1-ring mean operator; ``follow``: the share of the
    way moved a frame (default :data:`FOLD_FOLLOW`, read at the call; 1: no smoothing)."""
    follow = FOLD_FOLLOW if follow is None else float(follow)
    folds = np.asarray(folds, np.float64)
    if follow >= 1.0:
        return folds
    laplacian = _laplacian(folds, mean)
    before = np.stack([folds[i] if s is None else s.folds for i, s in enumerate(states)])
    laplacian_before = np.stack([laplacian[i] if s is None else s.laplacian for i, s in enumerate(states)])
    scale_before = np.array([1.0 if s is None else s.scale for s in states])
    followed = before + follow * (folds - before)
    followed_laplacian = laplacian_before + follow * (laplacian - laplacian_before)
    scale = scale_before + follow * (
        _size(laplacian) / np.maximum(_size(followed_laplacian), 1e-12) - scale_before
    )
    for i in range(len(states)):
        states[i] = FollowedFolds(followed[i], followed_laplacian[i], float(scale[i]))
    return scale[:, None, None] * followed


def _followed(values: np.ndarray, follow: float, first: np.ndarray | float) -> np.ndarray:
    """(T, ...) -> (T, ...): y[t] = y[t - 1] + follow (x[t] - y[t - 1]) from y[-1] = ``first``, the
    arithmetic of :func:`follow_folds` (a loop over frames: faster here than a filter along axis 0)."""
    out = np.empty_like(values)
    last = first
    for t in range(len(values)):
        last = out[t] = last + follow * (values[t] - last)
    return out


def follow_over_time(folds: np.ndarray, mean: csr_matrix, follow: float | None = None) -> np.ndarray:
    """(T, V, 3) one animation's fold term -> as it is shown (T, V, 3): :func:`follow_folds` frame by
    frame, as a stream steps it, with the Laplacian of the whole clip in one sparse product."""
    follow = FOLD_FOLLOW if follow is None else float(follow)
    folds = np.asarray(folds, np.float64)
    if follow >= 1.0 or not len(folds):
        return folds
    laplacian = _laplacian(folds, mean)
    followed = _followed(folds, follow, folds[0])
    ratio = _size(laplacian) / np.maximum(_size(_followed(laplacian, follow, laplacian[0])), 1e-12)
    return _followed(ratio, follow, 1.0)[:, None, None] * followed
