"""Scores against an ensemble of simulated truths: accuracy relative to the simulator's own chaos,
and plausibility relative to what the truths themselves do.

``pred`` is (T, V, 3) (one prediction) or (S, T, V, 3) (S samples of a prediction); ``members``
is (K, T, V, 3), K >= 2. Distances between two sequences are PVE (mean over frames and vertices
of the Euclidean distance, mm). Definitions (docs/evaluation.md repeats them):

- floor: mean PVE between two different members (mean over the K(K-1)/2 pairs): how far apart
  two equally valid simulations are.
- PVE to the members: mean over members of PVE(pred, member). A fresh simulation scores about the
  floor, so ``pve_floor_ratio`` = PVE to the members / floor is 1 for a prediction as good as
  the simulator itself; the perfect conditional mean scores about 0.71 (docs/method.md).
- PVE to the mean: PVE(pred, mean of the members).
- Energy score (mm): E|X - Y| - 1/2 E|X - X'| - 1/2 E|Y - Y'| with X, X' drawn from the
  prediction's samples and Y, Y' from the members, every expectation over all pairs (diagonal
  included): half the energy distance between the two empirical distributions. It is >= 0 and 0
  only when the samples are the members. For one prediction E|X - X'| = 0 and it is
  E|X - y| - 1/2 E|y - y'|.
- Draw spread (mm, with S > 1 samples: the sample mode's draws from S seeds): the mean PVE between
  two draws; over the floor (``draw_spread_ratio``) it says whether two seeds differ as two
  simulations do (1), less (a draw near the mean) or more.
- Plausibility, each as the prediction's value over the members' mean value: acceleration
  (mean ||second difference in time||; < 1 too smooth, > 1 jittery), bending and stretch energy
  (:func:`.metrics.cloth_energies`; < 1 too smooth or slack), hem swing
  (:func:`hrr_garment.sim.quality.hem_swing`). Jitter compares accelerations: mean over members of
  ||a(pred) - a(member)|| over the same between two members (the jitter floor).
"""

from __future__ import annotations

import itertools

import numpy as np

from ..motion.motion import Motion
from ..sim.quality import hem_swing
from .metrics import MeshTopology, cloth_energies


def _pve_mm(a: np.ndarray, b: np.ndarray) -> float:
    return 1000.0 * float(
        np.linalg.norm(np.asarray(a, np.float64) - np.asarray(b, np.float64), axis=-1).mean()
    )


def _samples(pred: np.ndarray) -> np.ndarray:
    return pred[None] if pred.ndim == 3 else pred


def mean_pairwise_mm(members: np.ndarray, distance=_pve_mm) -> float:
    """Mean distance over the distinct pairs of members (the floor for PVE)."""
    pairs = list(itertools.combinations(range(len(members)), 2))
    if not pairs:
        raise ValueError("the floor needs at least two members")
    return float(np.mean([distance(members[i], members[j]) for i, j in pairs]))


def energy_score_mm(pred: np.ndarray, members: np.ndarray) -> float:
    """Half the energy distance between the prediction's samples and the members (PVE as the norm)."""
    x, y = _samples(pred), members
    cross = np.mean([_pve_mm(a, b) for a in x for b in y])
    within_x = np.mean([_pve_mm(a, b) for a in x for b in x])
    within_y = np.mean([_pve_mm(a, b) for a in y for b in y])
    return float(cross - 0.5 * within_x - 0.5 * within_y)


def _acceleration(v: np.ndarray) -> np.ndarray:
    return np.diff(np.asarray(v, np.float64), 2, axis=-3)


def _mean_norm_mm(a: np.ndarray) -> float:
    return 1000.0 * float(np.linalg.norm(a, axis=-1).mean()) if a.size else 0.0


def truth_metrics(
    members: np.ndarray, motion: Motion, rest: np.ndarray, topo: MeshTopology, hem: np.ndarray | None = None
) -> dict[str, float]:
    """The members' own values (the floor and every ``truth_*`` key): one computation per sequence,
    shared by every mode scored against it."""
    out = {"floor_mm": mean_pairwise_mm(members)}
    if members.shape[1] >= 3:
        out["truth_jitter_mm"] = mean_pairwise_mm(_acceleration(members), lambda a, b: _mean_norm_mm(a - b))
    out.update({f"truth_{k}": v for k, v in _cloth_values(members, motion, rest, topo, hem).items()})
    return out


def _cloth_values(
    samples: np.ndarray, motion: Motion, rest: np.ndarray, topo: MeshTopology, hem: np.ndarray | None
) -> dict[str, float]:
    """Mean acceleration, stretch and bending energy and hem swing of samples (S, T, V, 3): the
    same quantities for a prediction and (as ``truth_*``) for the members."""
    out = {}
    if samples.shape[1] >= 3:
        out["acceleration_mm"] = _mean_norm_mm(_acceleration(samples))
    stretch, bend = zip(*(cloth_energies(s, rest, topo) for s in samples))
    out.update(stretch_energy=float(np.mean(stretch)), bending_energy=float(np.mean(bend)))
    if hem is not None and len(hem):
        out["hem_swing_m"] = float(np.mean([hem_swing(s, motion, hem) for s in samples]))
    return out


def ensemble_metrics(
    pred: np.ndarray,
    members: np.ndarray,
    motion: Motion,
    rest: np.ndarray,
    topo: MeshTopology,
    hem: np.ndarray | None = None,
    truth: dict[str, float] | None = None,
) -> dict[str, float]:
    """Accuracy and plausibility of one sequence's prediction against its truth ensemble.

    Absolute values (``*_mm``, energies, swing) are returned for the prediction and, prefixed
    ``truth_``, for the members (``truth``: :func:`truth_metrics` of these members, computed here
    when not given), so that sequences can be combined before taking ratios (:func:`ensemble_ratios`).
    """
    x = _samples(pred).astype(np.float64)
    point = x[0] if len(x) == 1 else x.mean(0)
    out = {
        **(truth if truth is not None else truth_metrics(members, motion, rest, topo, hem)),
        "pve_members_mm": float(np.mean([_pve_mm(s, m) for s in x for m in members])),
        "pve_ensemble_mean_mm": _pve_mm(point, members.astype(np.float64).mean(0)),
        "energy_score_mm": energy_score_mm(x, members),
    }
    if len(x) > 1:  # a generative mode's draws: how far apart two of them are, beside the floor
        out["draw_spread_mm"] = mean_pairwise_mm(x)
    if len(point) >= 3:
        acc_pred, acc_truth = _acceleration(x), _acceleration(members)
        out["jitter_mm"] = float(np.mean([_mean_norm_mm(a - b) for a in acc_pred for b in acc_truth]))
    out.update(_cloth_values(x, motion, rest, topo, hem))
    return out


RATIOS = (  # (name, prediction key, truth key)
    ("pve_floor_ratio", "pve_members_mm", "floor_mm"),
    ("jitter_ratio", "jitter_mm", "truth_jitter_mm"),
    ("acceleration_ratio", "acceleration_mm", "truth_acceleration_mm"),
    ("bending_energy_ratio", "bending_energy", "truth_bending_energy"),
    ("stretch_energy_ratio", "stretch_energy", "truth_stretch_energy"),
    ("hem_swing_ratio", "hem_swing_m", "truth_hem_swing_m"),
    ("draw_spread_ratio", "draw_spread_mm", "floor_mm"),  # two draws apart, over two simulations apart
)


def ensemble_ratios(values: dict[str, float]) -> dict[str, float]:
    """The ratios of RATIOS from (combined) absolute values; a ratio whose parts are missing is left out."""
    return {
        name: values[num] / values[den]
        for name, num, den in RATIOS
        if num in values and den in values and values[den] > 0
    }
