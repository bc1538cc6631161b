"""Motion memory: what the body did before the motion encoder's 10-frame window (a third of a
second), appended to the per-frame features (:mod:`.features`).

A loose skirt's hem still swings from a turn made a second ago; the window alone cannot see that
turn. Three kinds of memory, all filters of the frame's velocity features u_t (the 20 feature
joints' velocities and the root's, all 3-vectors in the body frame, and the yaw rate), and a clock:

- **Averages** over time constants s (``MemorySettings.seconds``):
  ``m_t = a R_t m_{t-1} + (1 - a) u_t``, ``a = exp(-1 / (fps s))``, ``m_0 = u_0``.
- **Resonators** at frequencies f (``MemorySettings.resonator_hz``) with damping ratio zeta: a damped
  pendulum bob hung from each velocity, ``x'' + 2 zeta w x' + w^2 x = -du/dt`` (w = 2 pi f), the
  linear model of a hem driven by the body's acceleration. The bob's displacement x and velocity
  q = u + x' are its state, ``s_t = A R_t s_{t-1} + B u_t`` with the exact (zero-order hold)
  discretisation of ``x' = q - u, q' = -w^2 x - 2 zeta w (q - u)``, at rest at the start
  (``x_0 = 0, q_0 = u_0``). The features are w x and q: where a pendulum of that period would be
  in its swing, which an average cannot say (an average has no phase).
- **Held averages** (``MemorySettings.held_seconds``): averages over time constants s of the time
  the body moves, ``h_t = b_t R_t h_{t-1} + (1 - b_t) u_t``, ``b_t = exp(-g_t / (fps s))``, g_t the
  frame's moving fraction (1 over :data:`MOVING_ABOVE`, 0 under :data:`STILL_BELOW`, linear
  between). While the body stands they keep what it did before it stopped: the turn or the run
  whose twist the skirt is still undoing, which an average forgets within its time constant.
- **A stillness clock** (``MemorySettings.still_seconds``): tau_t, the seconds the body has stood
  still. It is reset to 0 while the feature joints' mean speed is over :data:`MOVING_ABOVE` and
  counts 1 / fps a frame under :data:`STILL_BELOW`, a fraction of that between (a body swaying as it
  stands counts as standing, a gesture slows the count without resetting it); it never passes
  :data:`LONG_STILL_S`. The features are ``exp(-tau_t / s)`` for each s: 1 while the body moves,
  falling after it stops. A skirt twisted by a dance keeps untwisting for seconds after the body
  stands still (docs/materials.md, "After a stop"); the averages and resonators fade at their own
  rates whatever the cloth does, and none says how long ago the body stopped. Every motion's first
  frame reads LONG_STILL_S (the garment starts at rest), whatever its velocity: the offline
  features give frame 0 frame 1's velocities and the causal ones none, and the clock must not tell
  the two apart.

R_t turns last frame's body frame into this frame's (the yaw step from the yaw-rate feature), so
the filters are of the world velocities, seen from the body frame at t: like the features, it does
not change when the whole motion is moved or turned about the vertical axis (tested).

It is computed from the features alone, one frame after another, so offline clips, causal clips
and streams (:class:`MotionMemory`, carried per character) give the same values from the same
features. Models store their memory (``CodeSpaceSettings.memory_seconds``, ``resonator_hz``,
``resonator_damping``, ``held_seconds``, ``still_seconds``); none gives the 124 plain features of
models trained before it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.linalg import expm

from .features import FEATURE_DIM, SLICE_T, SLICE_V, SLICE_W
from .rotations import rotation_about_y

VECTORS = (
    SLICE_V.stop - SLICE_V.start + SLICE_T.stop - SLICE_T.start
) // 3  # 21: 20 joint velocities, the root's
MEMORY_WIDTH = (
    3 * VECTORS + 1
)  # values per average (and per resonator output): the 3-vectors and the yaw rate
# the stillness clock's ramp, the feature joints' mean speed in m/s: the standing parts of the
# library's bow, bye and raise-up clips read 0.01-0.04 (their 5th to 25th percentiles), a hand waved
# while standing about 0.05, its walks 0.75 or more (docs/codespace.md)
STILL_BELOW, MOVING_ABOVE = 0.05, 0.15
LONG_STILL_S = 1000.0  # the clock's reading at a motion's first frame, and its most


def check_memory_seconds(
    memory_seconds: Sequence[float], what: str = "memory time constants", unit: str = "seconds"
) -> tuple[float, ...]:
    """The values as a tuple of positive numbers, or a ValueError."""
    values = tuple(float(s) for s in memory_seconds)
    if any(not np.isfinite(s) or s <= 0 for s in values):
        raise ValueError(f"{what} must be positive {unit}, got {list(memory_seconds)}")
    return values


@dataclass(frozen=True)
class MemorySettings:
    """Which memory a model's features carry: averages over ``seconds``, resonators at
    ``resonator_hz`` with damping ratio ``damping``, held averages over ``held_seconds`` of moving
    time and a stillness clock read at ``still_seconds``."""

    seconds: tuple[float, ...] = ()
    resonator_hz: tuple[float, ...] = ()
    damping: float = 0.3
    still_seconds: tuple[float, ...] = ()  # the stillness clock's time constants; () for no clock
    held_seconds: tuple[float, ...] = ()  # the held averages' time constants (of moving time)

    def __post_init__(self) -> None:
        object.__setattr__(self, "seconds", check_memory_seconds(self.seconds))
        object.__setattr__(
            self, "held_seconds", check_memory_seconds(self.held_seconds, "held time constants")
        )
        object.__setattr__(
            self, "resonator_hz", check_memory_seconds(self.resonator_hz, "resonator frequencies", "hertz")
        )
        object.__setattr__(
            self, "still_seconds", check_memory_seconds(self.still_seconds, "stillness time constants")
        )
        object.__setattr__(self, "damping", float(self.damping))
        if not (np.isfinite(self.damping) and 0.0 < self.damping < 1.0):
            raise ValueError(
                f"resonator damping must be a ratio between 0 and 1 (underdamped), got {self.damping}"
            )

    @classmethod
    def of(cls, value: "MemorySettings | Sequence[float]") -> "MemorySettings":
        """A spec, or averages only from a sequence of time constants."""
        return value if isinstance(value, MemorySettings) else cls(tuple(value))

    @property
    def filter_rows(self) -> int:
        """Rows of MEMORY_WIDTH values the filters keep: one per average, two per resonator, one per
        held average."""
        return len(self.seconds) + 2 * len(self.resonator_hz) + len(self.held_seconds)

    @property
    def rows(self) -> int:
        """Rows of the state: the filters', then one for the stillness clock where there is one
        (tau in every column, so that the state stays one array)."""
        return self.filter_rows + bool(self.still_seconds)

    @property
    def width(self) -> int:
        """Feature columns the memory adds: 64 per filter row, one per stillness time constant."""
        return MEMORY_WIDTH * self.filter_rows + len(self.still_seconds)

    def __bool__(self) -> bool:
        return self.rows > 0


def feature_width(memory: MemorySettings | Sequence[float]) -> int:
    """Features per frame with ``memory``: 124 + 64 per average, 128 per resonator, 64 per held
    average and one per stillness time constant."""
    return FEATURE_DIM + MemorySettings.of(memory).width


def body_speed(features: np.ndarray) -> np.ndarray:
    """(N,) the feature joints' mean speed (m/s) of features (N, 124)."""
    v = features[:, SLICE_V].astype(np.float64).reshape(len(features), -1, 3)
    return np.linalg.norm(v, axis=-1).mean(-1)


def _still_ramp(speed: np.ndarray) -> np.ndarray:
    """(N,) how much of a frame at feature-joint mean ``speed`` (m/s) counts as standing: 1 under
    STILL_BELOW, 0 over MOVING_ABOVE, linear between (the clock's count in frames; the held
    averages' moving fraction is 1 less it)."""
    return np.clip((MOVING_ABOVE - speed) / (MOVING_ABOVE - STILL_BELOW), 0.0, 1.0)


def _clock_inputs(features: np.ndarray, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """(N,) whether each frame of features (N, 124) resets the clock (over MOVING_ABOVE), and (N,)
    the seconds it counts otherwise: 1 / fps under STILL_BELOW, a fraction of that between."""
    speed = body_speed(features)
    return speed > MOVING_ABOVE, _still_ramp(speed) / fps


def moving_fraction(features: np.ndarray) -> np.ndarray:
    """(N,) how much of each frame of features (N, 124) counts as moving, for the held averages: 1
    over MOVING_ABOVE, 0 under STILL_BELOW, linear between (1 less the clock's count, in frames)."""
    return 1.0 - _still_ramp(body_speed(features))


def _advanced(tau, moving, count):
    """The clock one frame on from ``tau``, given :func:`_clock_inputs`' values (arrays or scalars)."""
    return np.where(moving, 0.0, np.minimum(tau + count, LONG_STILL_S))


def clock_step(tau: np.ndarray, features: np.ndarray, fps: float) -> np.ndarray:
    """The clock readings tau (N,) one frame on, with this frame's features (N, 124): reset over
    MOVING_ABOVE, 1 / fps more under STILL_BELOW, a fraction of that between, at most LONG_STILL_S."""
    return _advanced(tau, *_clock_inputs(features, fps))


def still_clock(features: np.ndarray, fps: float) -> np.ndarray:
    """(T,) tau: the clock at each frame of one motion's features (T, 124), from LONG_STILL_S."""
    moving, count = _clock_inputs(features, fps)  # every frame's speed at once; only the sum loops
    tau = np.full(len(features), LONG_STILL_S)
    for t in range(1, len(features)):  # a recursion through a reset: no closed form
        tau[t] = _advanced(tau[t - 1], moving[t], count[t])
    return tau


def clock_values(tau: np.ndarray, still_seconds: Sequence[float]) -> np.ndarray:
    """(N, k) float32 features exp(-tau / s) of clock readings tau (N,)."""
    return np.exp(-np.asarray(tau, np.float64)[:, None] / np.asarray(still_seconds)[None]).astype(np.float32)


def resonator_step(hz: float, damping: float, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """The exact one-frame step (A (2, 2), B (2,)) of a resonator's state (x, q) driven by u."""
    w = 2.0 * np.pi * hz
    a = np.array([[0.0, 1.0], [-w * w, -2.0 * damping * w]])
    b = np.array([-1.0, 2.0 * damping * w])
    step = expm(a / fps)
    return step, np.linalg.solve(a, (step - np.eye(2)) @ b)


class MotionMemory:
    """The memory of N motions advanced one frame at a time (streams: one row per character).
    The state is (N, rows, 64): the averages, each resonator's x and q, the held averages, then the
    stillness clock's row (tau in every column) where there is one."""

    def __init__(self, memory: MemorySettings | Sequence[float], fps: float):
        self.spec, self.fps = MemorySettings.of(memory), float(fps)
        self.decay = np.exp(-1.0 / (fps * np.array(self.spec.seconds)))[
            :, None
        ]  # (k, 1): broadcast over (N, k, 64)
        steps = [resonator_step(f, self.spec.damping, fps) for f in self.spec.resonator_hz]
        self.resonator_a = np.array([a for a, _ in steps]).reshape(-1, 2, 2)  # (r, 2, 2)
        self.resonator_b = np.array([b for _, b in steps]).reshape(-1, 2)  # (r, 2)
        self.omega = 2.0 * np.pi * np.array(self.spec.resonator_hz)
        self.held_rate = (1.0 / (fps * np.array(self.spec.held_seconds)))[:, None]  # (h, 1), per moving frame
        # the same recursion as transfer functions for a whole clip (with_memory): s_t = A s_{t-1} + B u_t,
        # y_t = C s_t is a standard state space in s_{t-1} with outputs C A and C B; C = diag(w, 1)
        from scipy.signal import lfilter_zi, ss2tf  # a second's import: only a memory's filters need it

        self.resonator_filters = []
        for a, b, w in zip(self.resonator_a, self.resonator_b, self.omega):
            c = np.diag([w, 1.0])
            for row in range(2):
                num, den = ss2tf(a, b[:, None], (c @ a)[row : row + 1], (c @ b)[row : row + 1, None])
                self.resonator_filters.append((num[0], den, lfilter_zi(num[0], den)))

    def start(self, features: np.ndarray) -> np.ndarray:
        """The state (N, rows, 64) at a motion's first frame, from its features (N, 124): every
        average (held or not) at the first velocities, every bob at rest (x 0, q the first velocities)."""
        u = _velocities(features)
        k, r = len(self.spec.seconds), len(self.spec.resonator_hz)
        state = np.repeat(u[:, None], self.spec.filter_rows, 1)
        state[:, k : k + 2 * r : 2] = 0.0
        if self.spec.still_seconds:
            state = np.concatenate([state, np.full((len(u), 1, MEMORY_WIDTH), LONG_STILL_S)], 1)
        return state

    def step(self, state: np.ndarray, features: np.ndarray) -> np.ndarray:
        """The state (N, rows, 64) one frame on, from the last state and this frame's features (N, 124)."""
        n, rows, k = len(state), self.spec.filter_rows, len(self.spec.seconds)
        clock = state[:, rows:, :1]  # (N, 0 or 1, 1): not a vector, never turned
        if self.spec.still_seconds:
            clock = clock_step(clock[:, 0, 0], features, self.fps)[:, None, None]
        clock = np.repeat(clock, MEMORY_WIDTH, 2)
        turn = rotation_about_y(
            -features[:, SLICE_W][:, 0].astype(np.float64) / self.fps
        )  # (N, 3, 3): last body frame -> this
        vectors = state[:, :rows, :-1].reshape(n, rows, VECTORS, 3) @ np.swapaxes(turn, -1, -2)[:, None]
        carried = np.concatenate([vectors.reshape(n, rows, 3 * VECTORS), state[:, :rows, -1:]], -1)
        u = _velocities(features)[:, None]
        averages = self.decay * carried[:, :k] + (1.0 - self.decay) * u
        held_from = k + 2 * len(self.spec.resonator_hz)
        bobs = carried[:, k:held_from].reshape(n, -1, 2, MEMORY_WIDTH)
        bobs = self.resonator_a @ bobs + self.resonator_b[..., None] * u[:, None]
        held = carried[:, held_from:]
        if self.spec.held_seconds:
            hold = np.exp(-moving_fraction(features)[:, None, None] * self.held_rate)  # (N, h, 1)
            held = hold * held + (1.0 - hold) * u
        return np.concatenate([averages, bobs.reshape(n, -1, MEMORY_WIDTH), held, clock], 1)

    def advance(self, states: Sequence[np.ndarray | None], features: np.ndarray) -> np.ndarray:
        """N motions one frame on, each from its last state (rows, 64), or from its start where it
        has none (None: its first frame), with this frame's features (N, 124) -> (N, rows, 64)."""
        fresh = np.array([s is None for s in states], bool)
        out = np.empty((len(states), self.spec.rows, MEMORY_WIDTH))
        if fresh.any():
            out[fresh] = self.start(features[fresh])
        if not fresh.all():
            out[~fresh] = self.step(np.stack([s for s in states if s is not None]), features[~fresh])
        return out

    def values(self, state: np.ndarray) -> np.ndarray:
        """The state as feature columns (N, width), float32: the averages, w x and q, the held
        averages, the clock's."""
        k, rows = len(self.spec.seconds), self.spec.filter_rows
        out = state[:, :rows].copy()
        out[:, k : k + 2 * len(self.spec.resonator_hz) : 2] *= self.omega[None, :, None]
        out = out.reshape(len(state), -1).astype(np.float32)
        if not self.spec.still_seconds:
            return out
        return np.concatenate([out, clock_values(state[:, rows, 0], self.spec.still_seconds)], 1)


@lru_cache(maxsize=16)
def motion_memory(memory: MemorySettings, fps: float) -> MotionMemory:
    """A :class:`MotionMemory`, made once per spec and frame rate (a stream steps it every push)."""
    return MotionMemory(memory, fps)


def _velocities(features: np.ndarray) -> np.ndarray:
    """The remembered columns (N, 64) of features (N, 124): joint and root velocities, yaw rate."""
    return np.concatenate([features[:, SLICE_V], features[:, SLICE_T], features[:, SLICE_W]], 1).astype(
        np.float64
    )


def with_memory(features: np.ndarray, fps: float, memory: MemorySettings | Sequence[float]) -> np.ndarray:
    """(T, 124) features of one motion -> (T, feature_width) with its memory appended; unchanged
    (the same array) without any. The recursion of :class:`MotionMemory` in closed form: the
    velocities turned into the first frame's body frame (the yaw steps summed), linear filters
    there, turned back into each frame's body frame (the same values to rounding, tested)."""
    memory = motion_memory(MemorySettings.of(memory), float(fps))  # its resonators' steps made once
    if not memory.spec:
        return features
    heading = np.cumsum(features[:, SLICE_W][:, 0].astype(np.float64)) / fps  # yaw since frame 0 ...
    heading -= heading[0]  # ... frame 0's own step is before it
    to_first = rotation_about_y(heading)  # (T, 3, 3): frame t's body frame -> frame 0's
    from scipy.signal import lfilter  # a second's import: only a memory's filters need it

    out = np.empty((len(features), feature_width(memory.spec)), np.float32)
    out[:, :FEATURE_DIM] = features
    u = _velocities(features)
    if memory.spec.still_seconds:
        out[:, FEATURE_DIM + memory.spec.filter_rows * MEMORY_WIDTH :] = clock_values(
            still_clock(features, fps), memory.spec.still_seconds
        )
    vectors = u[:, :-1].reshape(len(u), VECTORS, 3) @ np.swapaxes(to_first, -1, -2)
    first = np.concatenate([vectors.reshape(len(u), -1), u[:, -1:]], 1)
    filtered = [lfilter([1.0 - a], [1.0, -a], first, axis=0, zi=a * first[:1])[0] for a in memory.decay[:, 0]]
    filtered += [
        lfilter(num, den, first, axis=0, zi=zi[:, None] * first[:1])[0]
        for num, den, zi in memory.resonator_filters
    ]
    if memory.spec.held_seconds:
        moving = moving_fraction(features)
        filtered += [_held_average(first, np.exp(-moving * rate)) for rate in memory.held_rate[:, 0]]
    for i, smoothed in enumerate(filtered):
        back = smoothed[:, :-1].reshape(len(u), VECTORS, 3) @ to_first
        cols = slice(FEATURE_DIM + i * MEMORY_WIDTH, FEATURE_DIM + (i + 1) * MEMORY_WIDTH)
        out[:, cols] = np.concatenate([back.reshape(len(u), -1), smoothed[:, -1:]], 1)
    return out


def _held_average(u: np.ndarray, hold: np.ndarray) -> np.ndarray:
    """(T, 64) h_t = hold_t h_{t-1} + (1 - hold_t) u_t from h_0 = u_0, of velocities u (T, 64) in one
    frame: a recursion whose factor changes each frame, which no fixed filter gives."""
    out = np.empty_like(u)
    out[0] = u[0]
    for t in range(1, len(u)):
        out[t] = hold[t] * out[t - 1] + (1.0 - hold[t]) * u[t]
    return out
