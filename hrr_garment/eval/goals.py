"""hrr-eval's comparative goals, from the paper's shape (docs/method.md): hybrid <= 0.5 x
regression-only and <= 0.85 x retrieval-only in PVE, learned retrieval <= 0.8 x naive NN, and an
interior optimum of tau; on the library protocol, the hybrid against the single modes. Each is
reported with its ratio and whether it is met; a goal whose modes were not evaluated is left out.
"""

from __future__ import annotations

import numpy as np

from .evaluate import TauPoint
from .mode_results import ModeResult

GOALS = (  # (name, numerator mode, denominator mode, target ratio)
    ("hybrid_vs_regression", "hybrid", "regression", 0.5),
    ("hybrid_vs_retrieval", "hybrid", "retrieval", 0.85),
    ("retrieval_vs_naive_nn", "retrieval", "naive-nn", 0.8),
    ("hybrid_vs_direct", "hybrid", "direct", None),
    ("residual_vs_regression", "residual", "regression", None),  # what the borrowed detail costs or gains
    ("detail_vs_regression", "detail", "regression", None),
)


def goals(modes: dict[str, ModeResult], sweep: list[TauPoint] | None) -> dict:
    """Each goal of GOALS (one mode's error over another's, against a target), and whether the tau
    sweep's optimum is interior."""
    out = {}
    for name, num, den, target in GOALS:
        if num in modes and den in modes:
            ratio = modes[num].metrics["pve_mm"] / max(modes[den].metrics["pve_mm"], 1e-12)
            out[name] = {
                "ratio": ratio,
                "target": target,
                "met": None if target is None else bool(ratio <= target),
            }
    if sweep:
        out["interior_tau_optimum"] = _best_tau(sweep)
    return out


# The paper's own ratios of per-vertex error (its Table 3: pleated and asymmetric skirts; Table 5:
# VB Dress03 and VB Skirt02, ground truth excluded from retrieval), lowest and highest
PAPER_RATIOS = {
    "hybrid_vs_regression": (0.366, 0.488),
    "hybrid_vs_retrieval": (0.797, 0.808),
    "retrieval_vs_naive_nn": (0.834, 0.902),
}
LIBRARY_TARGET = 0.7  # hybrid PVE over regression-only's on the library protocol


def _best_tau(sweep: list[TauPoint]) -> dict:
    """The sweep's lowest-error tau, and whether it is interior (neither never nor always retrieval)."""
    errors = [p.pve_mm for p in sweep]
    best = int(np.argmin(errors))
    interior = 0 < best < len(sweep) - 1 and 0 < sweep[best].retrieval_usage < 1
    return {
        "best_tau": sweep[best].tau,
        "best_pve_mm": errors[best],
        "retrieval_usage": sweep[best].retrieval_usage,
        "met": bool(interior),
    }


def library_goals(modes: dict[str, dict], sweep: list[TauPoint] | None) -> dict:
    """The library protocol's goals (report.json's mode entries): hybrid at most LIBRARY_TARGET x
    regression-only in PVE, a better energy score than both single modes (against the truth
    ensemble), and an interior tau optimum."""
    out = {}
    if "hybrid" in modes and "regression" in modes:
        ratio = modes["hybrid"]["metrics"]["pve_mm"] / max(modes["regression"]["metrics"]["pve_mm"], 1e-12)
        out["hybrid_vs_regression"] = {
            "ratio": ratio,
            "target": LIBRARY_TARGET,
            "met": bool(ratio <= LIBRARY_TARGET),
        }
    scores = {
        m: modes[m].get("ensemble", {}).get("energy_score_mm")
        for m in ("hybrid", "regression", "retrieval")
        if m in modes
    }
    if len(scores) == 3 and None not in scores.values():
        rival = min(scores["regression"], scores["retrieval"])
        out["energy_score_vs_single_modes"] = {
            "ratio": scores["hybrid"] / max(rival, 1e-12),
            "target": 1.0,
            "met": bool(scores["hybrid"] < rival),
        }
    if sweep:
        out["interior_tau_optimum"] = _best_tau(sweep)
    return out
