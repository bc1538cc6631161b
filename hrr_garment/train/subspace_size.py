"""The fast decoder's size (:mod:`.subspace`, the ``subspace`` stage): each candidate number of
components' validation error against the simulation, the fewest whose error is close enough to the
full decoder's, and a warning where the one kept is still far from it."""

from __future__ import annotations

import numpy as np
import torch

from ..models.subspace import SubspaceDecoder

CANDIDATES = (16, 32, 64, 96, 128, 192, 256, 384, 512)  # component counts tried, up to max_components


@torch.no_grad()
def validation_errors(
    model: SubspaceDecoder, latents: np.ndarray, truth: np.ndarray, batch: int = 256
) -> dict[int, float]:
    """Mean per-vertex error (mm) against ``truth`` of the first K components, for each candidate K:
    the network runs once a frame, each size keeping a prefix of its coefficients."""
    sizes = [c for c in CANDIDATES if c < model.components] + [model.components]
    totals = dict.fromkeys(sizes, 0.0)
    for i in range(0, len(latents), batch):
        coefficients = model.coefficients(torch.from_numpy(np.ascontiguousarray(latents[i : i + batch])))
        for k in sizes:
            pred = model.vertices(coefficients[:, :k]).numpy()
            totals[k] += float(np.linalg.norm(pred - truth[i : i + batch], axis=-1).sum())
    return {k: 1000.0 * total / (truth.shape[0] * truth.shape[1]) for k, total in totals.items()}


def pick_components(errors: dict[int, float], full_mm: float, tolerance: float) -> int:
    """The fewest components whose error is at most ``tolerance`` x ``full_mm``; where none is,
    the fewest within 1 % of the most accurate (more components would cost more for nothing)."""
    bound = (
        tolerance * full_mm if min(errors.values()) <= tolerance * full_mm else 1.01 * min(errors.values())
    )
    return min(k for k, e in errors.items() if e <= bound)


FAR_FROM_FULL = 1.5  # a fast decoder above this x the full decoder's validation error is worth a warning


def subspace_warning(entry: dict) -> str | None:
    """A warning where the distilled decoder kept (bundle.json ``subspace``) is far from the full
    one on validation (too few training frames, for one), else None."""
    ratio = entry["validation_mm"] / max(entry["full_validation_mm"], 1e-9)
    if ratio <= FAR_FROM_FULL:
        return None
    return (
        f"the fast decoder's validation error is {entry['validation_mm']:.2f} mm, {ratio:.1f} x the full "
        f"decoder's {entry['full_validation_mm']:.2f} mm: run this model with decoder='full' (more training "
        "frames, or subspace.model.hidden, bring it closer)"
    )
