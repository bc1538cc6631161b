"""Procedural motion library: deterministic per seed, smooth, feet planted without skating."""

from __future__ import annotations

import inspect

import numpy as np

from ...errors import HRRError
from ..motion import Motion
from .engine import build_motion
from .kinds import KINDS
from .posture import POSTURES, UPRIGHT, Posture, draw_posture

__all__ = ["KINDS", "synthesize", "kind_parameters", "Posture", "UPRIGHT"]


def kind_parameters(kind: str) -> list[str]:
    """Names of the tunable parameters of a kind (beyond seed and duration)."""
    return list(inspect.signature(KINDS[kind]).parameters)[2:]


def synthesize(
    kind: str, seconds: float = 6.0, seed: int = 0, *, posture: Posture | str = UPRIGHT, **params: float
) -> Motion:
    """Generate a canonical motion of ``kind`` lasting ``seconds`` (30 fps), its body carried as
    ``posture`` says: the kind's own upright body (``"upright"``, the default), ``"drawn"`` (a
    performer's carriage drawn with the seed, :mod:`.posture`; what the presets that ask for it
    simulate) or a given :class:`~.posture.Posture`."""
    if kind not in KINDS:
        raise HRRError(f"unknown motion kind {kind!r}; available: {', '.join(KINDS)}")
    unknown = set(params) - set(kind_parameters(kind))
    if unknown:
        raise HRRError(
            f"motion kind {kind!r} has no parameter(s) {sorted(unknown)}; it takes {kind_parameters(kind)}"
        )
    if not seconds > 0:
        raise HRRError(f"seconds must be positive, got {seconds}")
    rng = np.random.default_rng([seed, sorted(KINDS).index(kind)])
    plan = KINDS[kind](rng, float(seconds), **params)
    drawn = isinstance(posture, str) and posture == "drawn"
    if isinstance(posture, str) and posture in POSTURES:
        # drawn after the kind's draws: the same steps, only the carriage added
        posture = draw_posture(rng) if drawn else UPRIGHT
    elif not isinstance(posture, Posture):
        raise HRRError(f"posture must be a Posture or one of {POSTURES}, got {posture!r}")
    plan = posture.carried(plan)
    source = f"synth:{kind}:seed={seed}" + "".join(f":{k}={v}" for k, v in sorted(params.items()))
    source += ":posture=drawn" if drawn else ""
    return build_motion(plan, source)
