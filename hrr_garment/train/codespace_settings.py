"""The code-space stage's training settings (``codespace.train``: :class:`CodeSpaceTrainSettings`),
checked when made, and the choices they name (validation protocols, latent losses)."""

from __future__ import annotations

from dataclasses import dataclass

from ..settings import SettingsError, from_settings

VALIDATION_PROTOCOLS = ("clips", "windows")
LATENT_LOSSES = ("standardised", "vertex")
CONTACT_BODIES = (
    "visible",
    "capsules",
)  # the contact phase's body: the skin where a body has one, or capsules
PAPER_VALIDATION_FRACTION = 0.1  # "windows": the paper's 9:1 split of the training clips' windows


@dataclass(frozen=True)
class CodeSpaceTrainSettings:
    """The code-space stage's training settings (``codespace.train``)."""

    epochs: int = 300
    batch_size: int = 64
    learning_rate: float = 1e-3
    lr_final: float = 0.01  # cosine schedule over the run (epochs or budget) down to this x learning_rate
    weight_decay: float = 1e-4
    match_weight: float = 0.1  # stage 1
    match_weight_late: float = 0.5  # after the reconstruction plateau
    diversity: float = 0.05
    regress: float = 1.0  # weight of decoder(E(c_m)) vs z: trains the regression path directly
    temperature: float = 1.0  # Gumbel-Softmax temperature at epoch 0 ...
    temperature_decay: float = 0.98  # ... times this per epoch ...
    temperature_min: float = 0.3  # ... down to this
    plateau_patience: int = 8
    plateau_delta: float = 0.01  # relative improvement that counts as progress
    patience: int = 25  # epochs after the switch without a better validation regression loss
    max_minutes: float | None = (
        None  # a wall-clock cap on the epochs (a run it cuts short warns: pipeline.budget)
    )
    target_mm: float | None = (
        None  # validation regression error (window level) these settings reach on an idle machine
    )
    windows_per_epoch: int | None = 8192  # an epoch draws at most this many training windows (None: all)
    validation: str = "clips"  # "clips": the dataset's val split; "windows": the paper's 9:1 split of windows
    # how a latent window's error is measured: "standardised", the mean square of the standardised
    # latents; "vertex", the decoder's first-order vertex error (.vertex_metric), with vertex_ridge
    # of the former mixed in
    latent_loss: str = "standardised"
    vertex_ridge: float = 0.05
    # the contact phase after training (.contact): Adam steps on the decoder with the body's capsules
    # in the loss (0: none), the weight of the mean depth inside them (mm) beside the latent loss, and
    # how far outside the capsules that depth is counted from (metres: a clearance the decoded cloth
    # learns to keep, so that a test-time error of a few millimetres does not reach inside)
    contact_steps: int = 0
    contact_weight: float = 2.0
    contact_margin_m: float = 0.002
    # the body the phase keeps the cloth out of: "visible", the mesh the viewer sees where the body has
    # one (an anny body's, a fitted character's; the mannequin's is its capsules), or "capsules"
    contact_body: str = "visible"
    seed: int = 0

    def __post_init__(self) -> None:
        if self.validation not in VALIDATION_PROTOCOLS:
            raise SettingsError(
                f"code space training: validation must be one of {', '.join(VALIDATION_PROTOCOLS)}, "
                f"got {self.validation!r}"
            )
        if self.latent_loss not in LATENT_LOSSES:
            raise SettingsError(
                f"code space training: latent_loss must be one of {', '.join(LATENT_LOSSES)}, "
                f"got {self.latent_loss!r}"
            )
        if self.contact_body not in CONTACT_BODIES:
            raise SettingsError(
                f"code space training: contact_body must be one of {', '.join(CONTACT_BODIES)}, "
                f"got {self.contact_body!r}"
            )
        if self.contact_steps < 0 or self.contact_weight < 0:
            raise SettingsError(
                f"code space training: contact_steps and contact_weight must be at least 0, got "
                f"{self.contact_steps} and {self.contact_weight}"
            )
        if not 0.0 <= self.contact_margin_m <= 0.05:
            raise SettingsError(
                "code space training: contact_margin_m must be in [0, 0.05] metres, "
                f"got {self.contact_margin_m}"
            )
        if not 0.0 <= self.vertex_ridge <= 1.0:
            raise SettingsError(
                f"code space training: vertex_ridge must be in [0, 1], got {self.vertex_ridge}"
            )

    @classmethod
    def from_dict(cls, values: dict) -> "CodeSpaceTrainSettings":
        return from_settings(cls, values, "code space training")
