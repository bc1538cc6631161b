"""hrr-eval's plots: the error over time per mode, the motion-code entropy's histogram with tau,
and the tau sweep with plausibility beside accuracy (PNG, with the ``eval`` extra)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..io_utils import atomic_path
from .evaluate import TauPoint
from .mode_results import ModeResult
from .report import frame_entropies


def write_plots(
    folder: Path,
    modes: dict[str, ModeResult],
    sweep: list[TauPoint] | None,
    tau: float,
    gate: str = "entropy",
) -> list[str]:
    """error_over_time.png, entropy_histogram.png, tau_curve.png (with the ``eval`` extra); tau
    thresholds ``gate``'s signal (marked on the entropy histogram when that is the entropy)."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise ImportError(
            "hrr-eval plots need matplotlib: pip install 'hrr_garment[eval]' (or pass --no-plots)"
        ) from None
    written = []

    def save(fig, name):
        with atomic_path(folder / name) as tmp:
            fig.savefig(tmp, format="png", dpi=110, bbox_inches="tight")
        plt.close(fig)
        written.append(str(folder / name))

    fig, ax = plt.subplots(figsize=(10, 3.6))
    for mode, result in modes.items():
        ax.plot(np.concatenate([s.per_frame_pve_mm for s in result.sequences]), label=mode, lw=1)
    bounds = np.cumsum([s.frames for s in next(iter(modes.values())).sequences])[:-1]
    for b in bounds:
        ax.axvline(b, color="0.85", lw=0.8)
    ax.set(
        xlabel="frame (sequences one after another)", ylabel="per-vertex error (mm)", title="Error over time"
    )
    ax.legend(ncol=len(modes), fontsize=8)
    save(fig, "error_over_time.png")

    h = frame_entropies(modes)
    fig, ax = plt.subplots(figsize=(5, 3.4))
    ax.hist(h, bins=30, color="#4a6fc4")
    if gate == "entropy":
        ax.axvline(tau, color="#e0862d", lw=2, label=f"tau = {tau:.3f}")
        ax.legend()
    ax.set(xlabel="motion-code entropy (nats)", ylabel="frames", title="Entropy distribution")
    save(fig, "entropy_histogram.png")

    if sweep:
        finite = [p for p in sweep if math.isfinite(p.tau)]
        fig, ax = plt.subplots(figsize=(5, 3.4))
        ax.plot([p.tau for p in finite], [p.pve_mm for p in finite], "o-", color="#4a6fc4")
        ax.set(
            xlabel={
                "entropy": "tau (nats)",
                "similarity": "tau (1 - code similarity)",
                "distance": "tau (motion distance)",
            }.get(gate, "tau"),
            ylabel="hybrid PVE (mm)",
            title="Tau sweep",
        )
        ax2 = ax.twinx()  # plausibility beside accuracy: how much retrieval, and how sharp the result
        ax2.plot(
            [p.tau for p in finite],
            [100 * p.retrieval_usage for p in finite],
            "s--",
            color="#e0862d",
            label="retrieval usage",
        )
        ax2.plot(
            [p.tau for p in finite],
            [100 * p.sharpness for p in finite],
            "^:",
            color="#3a9b5c",
            label="sharpness (bending energy, % of the truth's)",
        )
        ax2.set_ylabel("%")
        ax2.legend(fontsize=7)
        save(fig, "tau_curve.png")
    return written
