"""The hem's swing restored: the latents' departure from their recent course, scaled up on free cloth.

The regression predicts a conditional mean, and a mean swings less than any sample: on real-quick's
held-out test clips the hem of the regression swings 0.66 of the simulation's, its default look
(the residual and folds) 0.78, where the mean of four truth simulations still swings 0.87 and the
conditional mean, extrapolated from means of two and four, about 0.83. Most of what is missing is
not chaos the motion cannot decide but the regression's damping of the swing it does decide.

Statistical speech synthesis met the same over-smoothing of its mean trajectories and restores
their variance (Toda and Tokuda 2007, *global variance*; Silén et al. 2012, *variance scaling*). Here
the regression's latents r_t are taken apart into their recent course, an exponential moving
average with a half-life of :data:`HALF_LIFE_S`, and their departure from it, which is scaled by
``gain`` on the free cloth (latent nodes hanging beyond :data:`FREE_CLOTH_MM` of the body at rest; 1
on the bodice, which lies on the body and must not move off it):

    mean_t = a mean_(t-1) + (1 - a) r_t,    z'_t = z_t + (g_node - 1) (r_t - mean_t)

Only the regression's own share is scaled, not what a mode adds to it: a match's departure is a
simulation's, which swings as much as the cloth does. Where the match's motion is the query's (the
game's own clips) the residual, ``r + c (m - r_m)`` with ``c`` its weight times the match's code
similarity, is ``(1 - c) r + c m``: the match replaces the share ``c`` of the regression, damping
included, so ``r_t`` above is ``(1 - c) r`` (:attr:`~.gate.WindowChoice.regression_part`). On the
game's own clips (``c`` 0.8) scaling all of the latents made the default output's energy score
1.006 x the regression's and all of the regression 1.016 x (0.977 without the gain).

The average looks only backwards, so the offline path, a stream and a crowd run the same recursion
from the same first frame and stay equal. The gain is the auto calibration's choice on validation
clips, within its allowance of PVE (:mod:`hrr_garment.eval.auto_mode`, bundle.json
``auto.swing_gain``); 1 leaves the latents as they are.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..artifacts.free_cloth import free_cloth_weights

HALF_LIFE_S = 1.0  # the recent course's half-life: about one stride, so a step's swing is departure
# the ramp (mm from the body at rest) from no gain to the full gain: the lower skirt. Measured on
# real-quick's validation clips at the same hem swing (0.83 of the simulation's), the gain on cloth
# beyond 20-60 mm cost 0.31 mm of PVE, beyond 60-150 mm 0.24, beyond 100-250 mm about 0.2
FREE_CLOTH_MM = (100.0, 250.0)
MAX_GAIN = 3.0


def valid_gain(value: object) -> bool:
    """Whether ``value`` is a swing gain: a number in (0, :data:`MAX_GAIN`]."""
    return (
        isinstance(value, (int, float, np.number))
        and not isinstance(value, bool)
        and 0.0 < float(value) <= MAX_GAIN
    )


@dataclass(frozen=True)
class SwingGain:
    """The swing's gain per latent node and the moving average's decay per frame."""

    gains: np.ndarray  # (nodes,) 1 on cloth near the body, up to the gain on free cloth
    decay: float  # a: the moving average keeps this share of its last value each frame

    @classmethod
    def of(cls, gain: float, node_hang_m: np.ndarray, fps: float) -> "SwingGain":
        """The gain on the nodes hanging ``node_hang_m`` (nodes,) from the body at rest, at ``fps``."""
        free = free_cloth_weights(node_hang_m, FREE_CLOTH_MM)
        decay = float(np.exp(-np.log(2.0) / (HALF_LIFE_S * float(fps))))
        return cls((1.0 + (float(gain) - 1.0) * free).astype(np.float32), decay)

    def step(
        self,
        latent: np.ndarray,
        regression: np.ndarray,
        mean: np.ndarray | None,
        fresh: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """One frame: ``latent`` (..., nodes, C), the ``regression``'s part of it (the same array
        where all of it is the regression's) and the regression's moving average so far (None: the
        first frame; ``fresh`` (N,) bool: the rows of a crowd that start here, whatever ``mean``
        holds) -> (the latent with the regression's departure scaled, the new average, float64)."""
        regression64 = regression.astype(np.float64)
        if mean is None:
            mean = regression64
        else:
            mean = self.decay * mean + (1.0 - self.decay) * regression64
            if fresh is not None and fresh.any():
                mean[fresh] = regression64[fresh]
        out = latent + (self.gains.reshape(-1, 1) - 1.0) * (regression64 - mean)
        return out.astype(np.float32), mean

    def apply(self, latents: np.ndarray, regression: np.ndarray | None = None) -> np.ndarray:
        """A clip's latents (T, nodes, C) and their regression's part (None: all of it), frame by
        frame from the first (as :meth:`step`)."""
        regression = latents if regression is None else regression
        out, mean = np.empty_like(latents, np.float32), None
        for t in range(len(latents)):
            out[t], mean = self.step(latents[t], regression[t], mean)
        return out


def swing_crowd(gain: SwingGain, chars: list, latents: np.ndarray) -> np.ndarray:
    """(N, nodes, C) a crowd's latents this frame with the swing restored, as :meth:`SwingGain.apply`
    does a clip: each character's regression part (``c.lod.regression``, its last window step's,
    else its whole latent) and that part's course, kept on the character (``c.swing_mean``, None
    before its first frame)."""
    fresh = np.array([c.swing_mean is None for c in chars])
    regression = np.stack(
        [latents[i] if c.lod.regression is None else c.lod.regression for i, c in enumerate(chars)]
    )
    means = np.stack(
        [
            regression[i].astype(np.float64) if c.swing_mean is None else c.swing_mean
            for i, c in enumerate(chars)
        ]
    )
    out, means = gain.step(latents, regression, means, fresh)
    for c, mean in zip(chars, means):
        c.swing_mean = mean
    return out
