"""The ``auto`` mode's criterion: which candidate a calibration's numbers pick, under which
allowances (:class:`AutoSettings`), and the candidates' labels. What the criterion is and why:
:mod:`hrr_garment.eval.auto_mode`, which measures the candidates on validation clips."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

from ..artifacts.auto_calibration import AutoCalibration, FreeCloth
from ..artifacts.folds import DETAIL_STRENGTH
from ..artifacts.manifest import AUTO_CHOICES, DETAIL_BASES
from ..settings import SettingsError, from_settings

AUTO_ALLOWANCE = 1.05  # the default allowance: candidates within 5 % of the most accurate PVE
PENETRATION_ALLOWANCE = 1.10  # and with at most 10 % more of the cloth inside the body than it,
PENETRATION_FLOOR_PCT = 1.0  # or 1 % of the vertices where that is more
DETAIL_STRENGTHS = (0.6, 0.8, 1.0)  # the folds' strengths measured (1: the simulated folds as they are)


@dataclass(frozen=True)
class AutoSettings:
    """The auto mode's calibration settings (the training configuration's ``auto`` section)."""

    allowance: float = AUTO_ALLOWANCE  # PVE a candidate may pay over the most accurate one's, as a factor
    # the vertices inside the body before the push-out a candidate may have, as a factor on the most
    # accurate one's
    penetration_allowance: float = PENETRATION_ALLOWANCE
    # ... or this share of the vertices (%) where that is more: small amounts are the push-out's
    penetration_floor_pct: float = PENETRATION_FLOOR_PCT

    def __post_init__(self) -> None:
        if not 1.0 <= self.allowance <= 2.0:
            raise SettingsError(
                f"auto: allowance is a factor on the most accurate PVE, from 1 to 2, got {self.allowance}"
            )
        if not 1.0 <= self.penetration_allowance <= 10.0:
            raise SettingsError(
                "auto: penetration_allowance is a factor on the most accurate candidate's cloth inside the "
                f"body, from 1 to 10, got {self.penetration_allowance}"
            )
        if not 0.0 <= self.penetration_floor_pct <= 100.0:
            raise SettingsError(
                "auto: penetration_floor_pct is a share of the vertices, 0 to 100, got "
                f"{self.penetration_floor_pct}"
            )

    @classmethod
    def from_dict(cls, values: dict) -> "AutoSettings":
        return from_settings(cls, values, "auto mode")

    def limits(self) -> dict[str, float]:
        """The allowances a calibration is picked under, as bundle.json's ``auto`` records them."""
        return {
            "allowance": self.allowance,
            "penetration_allowance": self.penetration_allowance,
            "penetration_floor_pct": self.penetration_floor_pct,
        }


def detail_label(base: str, strength: float) -> str:
    """A detail candidate's name in the calibration: ``detail x0.8``, ``detail on residual x1``."""
    return f"detail{'' if base == 'regression' else ' on ' + base} x{strength:g}"


#: the detail mode's candidates: label -> (base, strength)
DETAIL_CANDIDATES = {detail_label(b, s): (b, s) for b in DETAIL_BASES for s in DETAIL_STRENGTHS}
FREE_CLOTH = ", free cloth "  # a label's free-cloth suffix: "residual, free cloth 10-40 mm"
DEFAULT_BODY_PVE = "default_body_pve_mm"  # a candidate's PVE on the default body's validation clips alone
SWING = ", swing x"  # a label's swing suffix, last: "detail on residual x1, swing x1.2"
#: the gains on the free cloth's swing measured on the first pick (inference/swing.py)
SWING_GAINS = (1.2, 1.35, 1.5, 1.65, 1.8)
Candidates = Mapping[str, Mapping[str, float]]  # a calibration's measurements: label -> {metric: number}


def free_cloth_label(label: str, ramp_mm: tuple[float, float]) -> str:
    """A residual candidate's label on free cloth only: ``residual, free cloth 10-40 mm``."""
    return f"{label}{FREE_CLOTH}{ramp_mm[0]:g}-{ramp_mm[1]:g} mm"


def swing_label(label: str, gain: float) -> str:
    """A candidate's label with the free cloth's swing restored: ``detail on residual x1, swing x1.2``."""
    return f"{label}{SWING}{gain:g}"


def swing_of(label: str) -> float:
    """The swing gain of a candidate's label (1: none)."""
    _, _, gain = label.partition(SWING)
    return float(gain) if gain else 1.0


def without_swing(candidates: Candidates) -> dict[str, Mapping[str, float]]:
    """The candidates measured without a swing gain (those a first pick is made among)."""
    return {k: c for k, c in candidates.items() if SWING not in k}


def candidate_setting(label: str) -> tuple[str, str, float | None, tuple[float, float] | None]:
    """(mode, the detail mode's base, its strength or None, the free-cloth ramp in mm or None) of a
    candidate's label (a recorded calibration's too; its swing gain: :func:`swing_of`)."""
    head, _, ramp = label.partition(SWING)[0].partition(FREE_CLOTH)
    free = tuple(float(x) for x in ramp.removesuffix(" mm").split("-")) if ramp else None
    if head in DETAIL_CANDIDATES:
        return ("detail", *DETAIL_CANDIDATES[head], free)
    return head, "regression", None, free


def uses_residual(label: str) -> bool:
    """Whether a candidate adds the matches' residual (the residual mode, or detail on it)."""
    mode, base, _, _ = candidate_setting(label)
    return mode == "residual" or base == "residual"


def borrows(label: str) -> bool:
    """Whether a candidate adds something of the matches' (their residual or their folds): what a
    free-cloth ramp weights."""
    return uses_residual(label) or candidate_setting(label)[0] == "detail"


def plausibility_gap(sharpness: float, swing: float) -> float:
    """``hypot(ln sharpness, ln hem swing)``: 0 where both ratios are 1 (inf where one is 0)."""
    if sharpness <= 0 or swing <= 0:
        return math.inf
    return math.hypot(math.log(sharpness), math.log(swing))


def pick_auto_mode(candidates: Candidates, config: AutoSettings = AutoSettings()) -> str:
    """The criterion of the module docstring, under ``config``'s allowances, on each candidate's
    ``pve_mm``, ``sharpness`` and ``hem_swing`` (ratios to the truth) and, where recorded,
    ``penetration_pct`` (before the push-out; calibrations recorded before it have none, and are
    picked without it) and ``default_body_pve_mm`` (the PVE on the default body's clips alone, where
    the validation mixes it with other bodies); a candidate labelled by :data:`DETAIL_CANDIDATES` is
    the detail mode."""
    accurate = min(candidates, key=lambda m: candidates[m]["pve_mm"])
    best, inside = candidates[accurate]["pve_mm"], candidates[accurate].get("penetration_pct")
    most_inside = (
        None
        if inside is None
        else max(config.penetration_allowance * inside, config.penetration_floor_pct) + 1e-9
    )
    # the allowance on the default body's clips alone as well, where they were measured apart (a model
    # across bodies): a trade averaged over the bodies may cost the body every command uses more
    on_default = [c[DEFAULT_BODY_PVE] for c in candidates.values() if DEFAULT_BODY_PVE in c]
    default_best = min(on_default) if len(on_default) == len(candidates) else None
    eligible = [
        m
        for m, c in candidates.items()
        if c["pve_mm"] <= config.allowance * best
        and (most_inside is None or c.get("penetration_pct", 0.0) <= most_inside)
        and (default_best is None or c[DEFAULT_BODY_PVE] <= config.allowance * default_best)
    ]
    order = {m: i for i, m in enumerate(AUTO_CHOICES)}
    return min(
        eligible,
        key=lambda m: (
            plausibility_gap(candidates[m]["sharpness"], candidates[m]["hem_swing"]),
            order.get(candidate_setting(m)[0], len(order)),
            candidates[m]["pve_mm"],
        ),
    )


def pick_auto_and_detail(
    candidates: Candidates, config: AutoSettings = AutoSettings()
) -> tuple[str, str, float]:
    """(the mode auto runs, the detail mode's base, its strength) by the criterion on candidates
    labelled by mode, the detail mode's by :data:`DETAIL_CANDIDATES` (see the module docstring),
    under ``config``'s allowances."""
    picked, detail = _picked_labels(candidates, config)
    if detail is None:
        return candidate_setting(picked)[0], "regression", DETAIL_STRENGTH
    return candidate_setting(picked)[0], *candidate_setting(detail)[1:3]


def pick_free_cloth(candidates: Candidates, config: AutoSettings = AutoSettings()) -> FreeCloth | None:
    """The model's one free-cloth ramp (``(lo, hi)`` mm, None: the plain residual): the picked
    candidate's where it uses the residual, else the detail setting's where that does, else the
    criterion's pick among the residual mode's candidates (see the module docstring)."""
    picked, detail = _picked_labels(candidates, config)
    residuals = _of_mode(candidates, "residual")
    residual = pick_auto_mode(residuals, config) if residuals else None
    using = next(
        (label for label in (picked, detail, residual) if label is not None and uses_residual(label)), None
    )
    return None if using is None else candidate_setting(using)[3]


def pick_fold_ramp(candidates: Candidates, config: AutoSettings = AutoSettings()) -> FreeCloth | None:
    """The folds' free-cloth ramp (``(lo, hi)`` mm, None: the folds everywhere): the detail
    setting's, as it was measured (see the module docstring)."""
    detail = _picked_labels(candidates, config)[1]
    return None if detail is None else candidate_setting(detail)[3]


def _of_mode(candidates: Candidates, mode: str) -> dict[str, Mapping[str, float]]:
    """The candidates that run ``mode`` (each detail setting is the detail mode)."""
    return {k: c for k, c in candidates.items() if candidate_setting(k)[0] == mode}


def _picked_labels(candidates: Candidates, config: AutoSettings) -> tuple[str, str | None]:
    """The label auto picks, and the detail mode's setting (that label where it is a detail
    setting, else the criterion's pick among the detail candidates alone; None: there are none)."""
    picked = pick_auto_mode(candidates, config)
    details = _of_mode(candidates, "detail")
    if not details:
        return picked, None
    return picked, picked if picked in details else pick_auto_mode(details, config)


def picked_fields(
    candidates: Candidates, config: AutoSettings, *, folds_free_cloth: bool | None
) -> dict[str, Any]:
    """The fields of a calibration (:class:`~hrr_garment.artifacts.auto_calibration.AutoCalibration`)
    that the criterion picks from ``candidates`` under ``config``'s allowances: the mode, the detail
    look, the free-cloth ramps, the swing gain and the allowances picked under."""
    mode, detail_base, detail_strength = pick_auto_and_detail(candidates, config)
    # the folds' ramp only where the candidates were measured with it (calibrations recorded before
    # ran a ramp on the residual alone, and their folds run everywhere as they were measured)
    folds = {"folds_free_mm": pick_fold_ramp(candidates, config)} if folds_free_cloth else {}
    return {
        "mode": mode,
        "detail_base": detail_base,
        "detail_strength": detail_strength,
        **folds,
        "residual_free_mm": pick_free_cloth(candidates, config),
        "swing_gain": swing_of(pick_auto_mode(candidates, config)),
        **config.limits(),
    }


def repick(auto: AutoCalibration, config: AutoSettings) -> AutoCalibration:
    """A recorded calibration (``bundle.json``'s ``auto``) picked again under ``config``'s
    allowances: the candidates' numbers stand, only the choice among them moves."""
    fields = picked_fields(auto.candidates or {}, config, folds_free_cloth=auto.folds_free_cloth)
    return replace(auto, **fields)


def describe_auto(auto: AutoCalibration) -> str:
    """One line on a calibration (``bundle.json``'s ``auto``): the choice, the detail mode's setting
    and every candidate's numbers."""
    detail = f"x{auto.detail_strength:g} on the {auto.detail_base}"
    if auto.swing_gain is not None and auto.swing_gain != 1.0:
        detail += f"; the free cloth's swing x{auto.swing_gain:g}"
    if auto.residual_free_mm:
        detail += f"; the residual on free cloth {auto.residual_free_mm[0]:g}-{auto.residual_free_mm[1]:g} mm"
    if auto.folds_free_mm:
        detail += f"; the folds on free cloth {auto.folds_free_mm[0]:g}-{auto.folds_free_mm[1]:g} mm"
    allowance = (
        f"the most plausible within {100 * (auto.allowance - 1):.3g} % of the most accurate PVE"
        if auto.allowance is not None
        else ""
    )
    if allowance and auto.default_body_sequences:
        allowance += f" (on the default body's {auto.default_body_sequences} clips too)"
    if allowance and auto.penetration_allowance is not None:
        floor = 0 if auto.penetration_floor_pct is None else auto.penetration_floor_pct
        allowance += (
            f" and {100 * (auto.penetration_allowance - 1):.0f} % of its cloth inside the body "
            f"(or {floor:g} % of the vertices)"
        )
    allowance += "; " if allowance else ""
    return (
        f"auto mode: {auto.mode} ({allowance}the detail mode's folds {detail}; on {auto.sequences} "
        "validation clips: "
        + "; ".join(
            f"{m} {_shown(c['pve_mm'])} mm, sharpness {_shown(c['sharpness'])}, "
            f"hem swing {_shown(c['hem_swing'])}"
            + (f", {_shown(c['penetration_pct'])} % inside" if "penetration_pct" in c else "")
            for m, c in (auto.candidates or {}).items()
        )
        + ")"
    )


def _shown(number: float | None) -> str:
    """A candidate's number as the line shows it; a number that was not finite is stored as null
    (bundle.json is JSON) and shown as such rather than failing the line."""
    return "n/a" if number is None else f"{number:.2f}"
