"""The cloth settling after a stop: for a while after the body stops, the latents relax towards the
model's prediction with a time constant instead of following it at once.

When a body stops dead, the simulated hem falls back from its swing within a second or two and
then creeps towards rest for several more (docs/materials.md, "After a stop"): how far it has still
to go is the cloth's own state, which the motion, standing still, no longer says. A model reads the
motion alone, so it holds the shape of the stop for a while and then comes to rest in one step,
seconds early (0.45-0.61 of the simulation's settle time on held-out clips in three cloths). A
first-order lag of the output after a stop gives it some of the cloth's memory back:

    y_t = k_t y_(t-1) + (1 - k_t) z_t,    k_t = still_t exp(-1 / (fps s_t)),
    s_t = s max(0, 1 - tau_t / (FADE s))

``z_t`` the frame's latents (after the swing, stage 5), ``still_t`` in [0, 1] how much the frame
counts as standing (the stillness clock's ramp on the feature joints' speed,
:func:`hrr_garment.motion.memory.moving_fraction`: 1 under 0.05 m/s, 0 over 0.15), ``tau_t`` the
stillness clock (seconds since the body stopped, :func:`~hrr_garment.motion.memory.still_clock`)
and ``s`` the time constant asked. While the body moves ``k`` is 0 and the latents are the model's.
The lag fades out as the stillness clock reads :data:`FADE` time constants (the clock counts a
frame in full once the body is under 0.05 m/s, a share of it up to 0.15): by then the relaxation is done,
and a body that has stood longer (a wave, a bow, a talk) moves its cloth by its gestures, which the
model predicts and a lag would only delay (on held-out clips of standing gestures an unfaded lag of
1 s cost 9-12 % of PVE). The lag looks only backwards, so the offline path, a stream, a crowd and
the torch step (a crowd on a torch device, the ONNX graph: :mod:`.torch_settle`) run the same
recursion from the same first frame. It runs where a run asks for it (``settle``, ``hrr-animate
--settle S``, ``hrr-export-model --onnx --settle S``): a look, whose measured trade is in
docs/materials.md; 0 leaves the latents as they are.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..motion.memory import LONG_STILL_S, clock_step, moving_fraction, still_clock

MAX_SETTLE_S = 20.0  # the longest time constant a run may ask for (s)
FADE = 4.0  # the lag fades out over this many time constants after the stop


def valid_settle(value: object) -> bool:
    """Whether ``value`` is a settle time constant: a number in [0, :data:`MAX_SETTLE_S`] seconds."""
    return (
        isinstance(value, (int, float, np.number))
        and not isinstance(value, bool)
        and 0.0 <= float(value) <= MAX_SETTLE_S
    )


@dataclass(frozen=True)
class SettleLag:
    """The lag at a time constant and a frame rate."""

    seconds: float  # s: the time constant right after the stop
    fps: float

    def __post_init__(self) -> None:
        if not (self.seconds > 0 and self.fps > 0):
            raise ValueError(f"a settling lag needs seconds > 0 and fps > 0, got {self.seconds}, {self.fps}")

    def keep(self, features: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """(N,) the share of the last output each frame keeps: frames' features (N, >= 124, the plain
        ones first) and their stillness clock readings ``tau`` (N,)."""
        lag = self.seconds * np.clip(1.0 - np.asarray(tau, np.float64) / (FADE * self.seconds), 0.0, 1.0)
        keep = np.zeros(len(lag))
        on = lag > 0  # the exponential only where the lag is on: it underflows as the lag fades
        with np.errstate(under="ignore"):
            keep[on] = np.exp(-1.0 / (self.fps * lag[on]))
        return (1.0 - moving_fraction(features)) * keep

    @staticmethod
    def step(latent: np.ndarray, last: np.ndarray, keep: np.ndarray) -> np.ndarray:
        """One frame: ``latent`` (N, nodes, C), the last outputs and each row's ``keep`` (N,) ->
        this frame's outputs, float32."""
        k = keep.reshape(-1, 1, 1)
        return (k * last + (1.0 - k) * latent).astype(np.float32)

    def apply(self, latents: np.ndarray, features: np.ndarray) -> np.ndarray:
        """A clip's latents (T, nodes, C) lagged, each frame's keep from the clip's features (T, F),
        frame by frame from the first (as :meth:`step`)."""
        keep = self.keep(features, still_clock(features, self.fps))
        out = np.empty_like(latents, np.float32)
        out[0] = latents[0]
        for t in range(1, len(latents)):
            out[t] = self.step(latents[t][None], out[t - 1][None], keep[t : t + 1])[0]
        return out


def settle_crowd(lag: SettleLag, chars: list, latents: np.ndarray, *, features: np.ndarray) -> np.ndarray:
    """(N, nodes, C) a crowd's latents this frame lagged as :meth:`SettleLag.apply` lags a clip, each
    character's last output and stillness clock kept on it (``c.settled``: None before its first
    frame). ``features``: the characters' features this frame (N, F)."""
    fresh = np.array([c.settled is None for c in chars])
    tau = np.array([LONG_STILL_S if c.settled is None else c.settled[1] for c in chars])
    tau = np.where(fresh, LONG_STILL_S, clock_step(tau, features, lag.fps))
    last = np.stack([latents[i] if f else c.settled[0] for i, (c, f) in enumerate(zip(chars, fresh))])
    out = lag.step(latents, last, np.where(fresh, 0.0, lag.keep(features, tau)))
    for c, row, reading in zip(chars, out, tau):
        c.settled = (row, float(reading))
    return out
