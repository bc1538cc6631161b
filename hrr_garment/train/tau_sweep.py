"""The sweep over the gate's threshold tau: the hybrid's error where every window whose doubt is
below tau retrieves and every other regresses, a cheap selection between two precomputed errors per
window. tau = 0 is regression only, tau above the largest doubt retrieval only; the sweep's tau is its
lowest mean error (ties: the smallest tau, i.e. the least retrieval)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass
class TauSweep:
    """The hybrid's error and retrieval usage at each tau, and the best tau."""

    taus: list[float]
    errors_mm: list[float]
    retrieval_usage: list[float]  # fraction of windows retrieved
    best_tau: float

    def to_dict(self) -> dict:
        return {
            "taus": [t if math.isfinite(t) else "inf" for t in self.taus],
            "errors_mm": self.errors_mm,
            "retrieval_usage": self.retrieval_usage,
            "best_tau": self.best_tau,
        }


def sweep_tau(
    doubt: np.ndarray, regression_err: np.ndarray, retrieval_err: np.ndarray, steps: int = 20
) -> TauSweep:
    """Hybrid error for tau at 0, the doubt's quantiles and above its maximum (retrieval only, and a
    finite threshold a bundle can store: a window more doubtful than any seen regresses); picks the
    lowest."""
    quantiles = np.quantile(doubt, np.linspace(0, 1, steps + 1)) if len(doubt) else np.zeros(0)
    top = float(np.max(doubt)) + 1.0 if len(doubt) else math.inf
    taus = sorted({0.0, *[float(q) + 1e-6 for q in quantiles], top})
    errors, usage = [], []
    for tau in taus:
        retrieve = doubt < tau
        errors.append(float(np.where(retrieve, retrieval_err, regression_err).mean()))
        usage.append(float(retrieve.mean()))
    best = int(np.argmin(errors))  # first minimum: the smallest tau among ties
    return TauSweep(taus, errors, usage, taus[best])
