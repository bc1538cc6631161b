"""The inference modes: one name for each, in one place (the CLI choices, the animator's checks,
the evaluation's list)."""

from __future__ import annotations

import enum


class Mode(str, enum.Enum):
    """How a garment latent is chosen per window. A ``str`` subclass: ``Mode.HYBRID == "hybrid"``,
    and it formats as its value."""

    AUTO = "auto"  # the model's calibrated choice among hybrid, residual, detail, sample (eval/auto_mode.py)
    HYBRID = "hybrid"  # retrieval where the motion code's entropy is below tau, else regression
    REGRESSION = "regression"  # the code-space decoder's latents
    RETRIEVAL = "retrieval"  # the database window with the nearest garment code
    RESIDUAL = "residual"  # regression plus the nearest window's detail (artifacts/residual.py)
    # the regression's or the residual mode's shape (as calibrated) plus the nearest window's folds
    # (inference/detail.py)
    DETAIL = "detail"
    NAIVE_NN = "naive-nn"  # the database window with the nearest standardised motion (a baseline)
    DIRECT = "direct"  # the direct-regression baseline (a GRU; offline only, when the bundle has it)
    # a draw of the cloth's distribution: the regression's latents plus the generative decoder's
    # departure, frame by frame (causal; models/sampler.py, when the bundle has it)
    SAMPLE = "sample"

    def __str__(self) -> str:
        return self.value

    def __format__(self, spec: str) -> str:
        return format(self.value, spec)

    @property
    def regresses(self) -> bool:
        """Whether the code-space decoder runs (hybrid, regression, residual, detail and sample; auto is
        resolved to one of these first, :meth:`~hrr_garment.inference.run_settings.RunSettings.resolve`)."""
        return self in (Mode.HYBRID, Mode.REGRESSION, Mode.RESIDUAL, Mode.DETAIL, Mode.SAMPLE)


#: the modes that run the motion encoder and the gate (offline, causal and streaming)
CODE_MODES = (
    Mode.HYBRID,
    Mode.REGRESSION,
    Mode.RETRIEVAL,
    Mode.RESIDUAL,
    Mode.DETAIL,
    Mode.NAIVE_NN,
    Mode.SAMPLE,
)
