"""The ``auto`` mode's calibration: which of the hybrid, residual and detail modes a model runs
by default, and how the detail mode runs.

Against a chaotic truth the most accurate output is close to the conditional mean, and the mean is
blurry: its folds and its hem's swing average away. The modes that use the database trade a little
accuracy for real simulated detail (docs/decisions/0009-auto-mode-default.md). ``auto`` is the calibrated trade, chosen on
the validation clips through the product path (``Animator.animate``: offline, blended, push-out on)
by one documented criterion that counts both:

1. accuracy first: the candidates whose PVE is within the allowance (``auto.allowance`` in the
   training configuration, :class:`AutoConfig`: 1.05, 5 %) of the most accurate candidate's. A
   sample of the truth's own distribution is about 1.4 x the PVE of its conditional mean, so cloth
   that looks like cloth costs PVE; 5 % of it for folds and swing that look real is the default's
   trade (issue 49's decision; it was 3 %). And no more cloth inside the body: a candidate may put
   at most ``auto.penetration_allowance`` (1.10) times the vertices inside the body (before the
   push-out) that the most accurate one does, or ``auto.penetration_floor_pct`` (1 %) of them where
   that is more (below it the push-out's work is small, and detail is not given up for it). A
   match's swing, brought by the residual mode, is another simulation's cloth, on another body for
   a model across bodies: on the unseen short-heavy body it took the vertices inside from 3.0 to
   3.9 % (the folds alone to 3.3 %);
2. then plausibility: of those, the one whose cloth looks most like the simulation, i.e. the
   smallest *plausibility gap* ``hypot(ln sharpness, ln hem swing)``, sharpness being the bending
   energy over the truth's and hem swing the hem's amplitude over the truth's (0: both as in the
   simulation; a half and a double are equally far, and a gain in either counts);
3. ties: the cheaper mode (hybrid, then residual, then detail: the order of :data:`AUTO_CHOICES`),
   then the more accurate.

The detail mode is measured in several settings (:data:`DETAIL_CANDIDATES`): its simulated folds at
each of :data:`DETAIL_STRENGTHS`, on the regression's latents and, where the residual mode runs, on
the residual mode's (which bring the match's swing). The folds' strength is the trade itself: on
held-out real clips the sharpness grows with it faster than the error (docs/decisions/0005-detail-strength-calibrated.md). The
criterion picks among all candidates; the detail mode's setting is the picked one's, or, where auto
is not a detail mode, the one the criterion picks among the detail candidates alone (what
``--mode detail`` runs).

Every candidate that uses the residual is also measured on free cloth only
(:data:`~hrr_garment.artifacts.residual.FREE_CLOTH_RAMPS_MM`, labelled ``..., free cloth 10-40
mm``): the match's deviation weighted per region by how far it hangs from the body, so that the
skirt takes the match's swing and the bodice keeps the regression's contact. The model keeps one
ramp (``auto.residual_free_mm``): the picked candidate's where it uses the residual, else the
detail setting's where that does, else the one the criterion picks among the residual mode's.

Last, the first pick is measured again with the free cloth's swing restored at each of
:data:`SWING_GAINS` (:mod:`hrr_garment.inference.swing`, labelled ``..., swing x1.2``) and the
criterion picks again among all candidates: a regression swings less than the cloth, so a gain
wins where it brings the swing closer to the truth's within the allowance. The model keeps the
picked candidate's gain (``auto.swing_gain``, 1 where the pick has none); it runs in the mode auto
picks, not in a mode named.
"""

from __future__ import annotations

import math
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np
from tqdm import tqdm

from ..artifacts.bundle import Bundle
from ..artifacts.folds import DETAIL_STRENGTH
from ..artifacts.manifest import AUTO_CHOICES, DETAIL_BASES
from ..artifacts.residual import FREE_CLOTH_RAMPS_MM
from ..data.dataset import SequenceRecord
from ..garment.fit import hem_vertices
from ..inference.animator import Animator
from ..inference.fold_track import FOLD_FOLLOW
from ..inference.run_settings import DetailLook
from ..inference.swing import HALF_LIFE_S
from ..settings import SettingsError, from_settings
from ..sim.quality import hem_swing
from . import metrics as M

AUTO_MAX_SEQUENCES = 24  # validation clips the choice animates at most (evenly spaced): about a minute
AUTO_ALLOWANCE = 1.05  # the default allowance: candidates within 5 % of the most accurate PVE
PENETRATION_ALLOWANCE = 1.10  # and with at most 10 % more of the cloth inside the body than it,
PENETRATION_FLOOR_PCT = 1.0  # or 1 % of the vertices where that is more
DETAIL_STRENGTHS = (0.6, 0.8, 1.0)  # the folds' strengths measured (1: the simulated folds as they are)


@dataclass(frozen=True)
class AutoConfig:
    """The auto mode's calibration settings (the training configuration's ``auto`` section)."""

    allowance: float = AUTO_ALLOWANCE  # PVE a candidate may pay over the most accurate one's, as a factor
    # the vertices inside the body before the push-out a candidate may have, as a factor on the most
    # accurate one's
    penetration_allowance: float = PENETRATION_ALLOWANCE
    # ... or this share of the vertices (%) where that is more: small amounts are the push-out's
    penetration_floor_pct: float = PENETRATION_FLOOR_PCT

    def __post_init__(self) -> None:
        if not 1.0 <= self.allowance <= 2.0:
            raise SettingsError(f"auto: allowance is a factor on the most accurate PVE, from 1 to 2, got {self.allowance}")
        if not 1.0 <= self.penetration_allowance <= 10.0:
            raise SettingsError("auto: penetration_allowance is a factor on the most accurate candidate's cloth inside the "
                                f"body, from 1 to 10, got {self.penetration_allowance}")
        if not 0.0 <= self.penetration_floor_pct <= 100.0:
            raise SettingsError(f"auto: penetration_floor_pct is a share of the vertices, 0 to 100, got {self.penetration_floor_pct}")

    @classmethod
    def from_dict(cls, values: dict) -> "AutoConfig":
        return from_settings(cls, values, "auto mode")

    def limits(self) -> dict[str, float]:
        """The allowances a calibration is picked under, as bundle.json's ``auto`` records them."""
        return {"allowance": self.allowance, "penetration_allowance": self.penetration_allowance,
                "penetration_floor_pct": self.penetration_floor_pct}


def detail_label(base: str, strength: float) -> str:
    """A detail candidate's name in the calibration: ``detail x0.8``, ``detail on residual x1``."""
    return f"detail{'' if base == 'regression' else ' on ' + base} x{strength:g}"


#: the detail mode's candidates: label -> (base, strength)
DETAIL_CANDIDATES = {detail_label(b, s): (b, s) for b in DETAIL_BASES for s in DETAIL_STRENGTHS}
FREE_CLOTH = ", free cloth "  # a label's free-cloth suffix: "residual, free cloth 10-40 mm"
SWING = ", swing x"  # a label's swing suffix, last: "detail on residual x1, swing x1.2"
#: the gains on the free cloth's swing measured on the first pick (inference/swing.py)
SWING_GAINS = (1.2, 1.35, 1.5, 1.65, 1.8)


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


def plausibility_gap(sharpness: float, swing: float) -> float:
    """``hypot(ln sharpness, ln hem swing)``: 0 where both ratios are 1 (inf where one is 0)."""
    if sharpness <= 0 or swing <= 0:
        return math.inf
    return math.hypot(math.log(sharpness), math.log(swing))


def pick_auto_mode(candidates: dict[str, dict[str, float]], config: AutoConfig = AutoConfig()) -> str:
    """The criterion of the module docstring, under ``config``'s allowances, on each candidate's
    ``pve_mm``, ``sharpness`` and ``hem_swing`` (ratios to the truth) and, where recorded,
    ``penetration_pct`` (before the push-out; calibrations recorded before it have none, and are
    picked without it); a candidate labelled by :data:`DETAIL_CANDIDATES` is the detail mode."""
    accurate = min(candidates, key=lambda m: candidates[m]["pve_mm"])
    best, inside = candidates[accurate]["pve_mm"], candidates[accurate].get("penetration_pct")
    most_inside = None if inside is None else \
        max(config.penetration_allowance * inside, config.penetration_floor_pct) + 1e-9
    eligible = [m for m, c in candidates.items() if c["pve_mm"] <= config.allowance * best
                and (most_inside is None or c.get("penetration_pct", 0.0) <= most_inside)]
    order = {m: i for i, m in enumerate(AUTO_CHOICES)}
    return min(eligible, key=lambda m: (plausibility_gap(candidates[m]["sharpness"], candidates[m]["hem_swing"]),
                                        order.get(candidate_setting(m)[0], len(order)), candidates[m]["pve_mm"]))


def pick_auto_and_detail(candidates: dict[str, dict[str, float]],
                         config: AutoConfig = AutoConfig()) -> tuple[str, str, float]:
    """(the mode auto runs, the detail mode's base, its strength) by the criterion on candidates
    labelled by mode, the detail mode's by :data:`DETAIL_CANDIDATES` (see the module docstring),
    under ``config``'s allowances."""
    picked, detail = _picked_labels(candidates, config)
    if detail is None:
        return candidate_setting(picked)[0], "regression", DETAIL_STRENGTH
    return candidate_setting(picked)[0], *candidate_setting(detail)[1:3]


def pick_free_cloth(candidates: dict[str, dict[str, float]], config: AutoConfig = AutoConfig()) -> list[float] | None:
    """The model's one free-cloth ramp (``[lo, hi]`` mm, None: the plain residual): the picked
    candidate's where it uses the residual, else the detail setting's where that does, else the
    criterion's pick among the residual mode's candidates (see the module docstring)."""
    picked, detail = _picked_labels(candidates, config)
    residuals = _of_mode(candidates, "residual")
    residual = pick_auto_mode(residuals, config) if residuals else None
    using = next((label for label in (picked, detail, residual) if label is not None and uses_residual(label)), None)
    ramp = None if using is None else candidate_setting(using)[3]
    return None if ramp is None else list(ramp)


def _of_mode(candidates: dict[str, dict[str, float]], mode: str) -> dict[str, dict[str, float]]:
    """The candidates that run ``mode`` (each detail setting is the detail mode)."""
    return {k: c for k, c in candidates.items() if candidate_setting(k)[0] == mode}


def _picked_labels(candidates: dict[str, dict[str, float]], config: AutoConfig) -> tuple[str, str | None]:
    """The label auto picks, and the detail mode's setting (that label where it is a detail
    setting, else the criterion's pick among the detail candidates alone; None: there are none)."""
    picked = pick_auto_mode(candidates, config)
    details = _of_mode(candidates, "detail")
    if not details:
        return picked, None
    return picked, picked if picked in details else pick_auto_mode(details, config)


def followed_otherwise(auto: dict) -> bool:
    """Whether a recorded calibration's detail candidates ran with folds followed in time otherwise
    than this version's (recorded before the following: as they came, 1)."""
    return float(auto.get("fold_follow", 1.0)) != FOLD_FOLLOW


def lacks_swing(auto: dict) -> bool:
    """Whether a recorded calibration has no swing candidates measured as the swing now runs
    (recorded before the swing's gain, or with another half-life)."""
    return not any(SWING in k for k in auto["candidates"]) or auto.get("swing_half_life_s") != HALF_LIFE_S


def lacks_free_cloth(auto: dict, residual: dict | None) -> bool:
    """Whether a recorded calibration measured the residual mode (of a calibrated weight,
    bundle.json's ``residual``) but not on free cloth: recorded before those candidates."""
    weight = (residual or {}).get("weight", 0.0)
    return weight > 0 and "residual" in auto["candidates"] and not any(FREE_CLOTH in k for k in auto["candidates"])


@contextmanager
def free_cloth(bundle: Bundle, ramp_mm: tuple[float, float] | None):
    """The bundle's residual on free cloth with ``ramp_mm`` (None: plain) while the block runs: a
    calibration measuring its candidates (bundle.json ``auto.residual_free_mm``, in memory only)."""
    had, before = "auto" in bundle.meta, bundle.meta.get("auto")
    bundle.meta["auto"] = {**bundle.auto, "residual_free_mm": None if ramp_mm is None else list(ramp_mm)}
    try:
        yield
    finally:
        if had:
            bundle.meta["auto"] = before
        else:
            del bundle.meta["auto"]


def calibrate_auto_mode(animator: Animator, records: list[SequenceRecord], config: AutoConfig = AutoConfig(),
                        max_sequences: int | None = AUTO_MAX_SEQUENCES, progress: bool = True) -> dict:
    """Each candidate's PVE (mm, against each record's simulation), sharpness, hem swing and
    vertices inside the body before the push-out (%) on ``records`` (at most ``max_sequences`` of
    them, evenly spaced), and the mode the criterion picks under ``config``: ``{"mode",
    "detail_base", "detail_strength", "criterion", the allowances (:meth:`AutoConfig.limits`),
    "sequences", "frames", "fold_follow", "candidates": {label: {...}}}``, what bundle.json keeps
    under ``auto`` (``fold_follow``: the folds' following in time the candidates ran with,
    :data:`~hrr_garment.inference.fold_track.FOLD_FOLLOW`)."""
    if not records:
        raise ValueError("the auto mode is calibrated on validation sequences, and there are none")
    if max_sequences is not None and len(records) > max_sequences:
        records = [records[i] for i in np.linspace(0, len(records) - 1, max_sequences).round().astype(int)]
    template = animator.bundle.template
    rest, topo = template.vertices.astype(np.float64), M.MeshTopology.of(template.faces, template.num_vertices)
    hem = hem_vertices(template)
    bundle = animator.bundle
    residual = bundle.has_residual and bundle.residual_weight > 0
    labels = [m for m in AUTO_CHOICES if m != "detail" and animator.supports(m)]
    if animator.supports("detail"):
        labels += [label for label, (base, _) in DETAIL_CANDIDATES.items() if base == "regression" or residual]
    if residual:
        labels += [free_cloth_label(label, ramp) for ramp in FREE_CLOTH_RAMPS_MM for label in labels if uses_residual(label)]
    names = list(animator.bundle.database.names)
    truths = [r.garment.astype(np.float64) for r in records]
    frames = sum(len(t) for t in truths)
    truth_bend = sum(float(M.cloth_energies(t, rest, topo)[1].sum()) for t in truths)
    truth_swing = sum(hem_swing(t, r.motion, hem) * len(t) for t, r in zip(truths, records))

    def measure(label: str) -> dict[str, float]:
        mode, base, strength, ramp = candidate_setting(label)
        look = DetailLook(base, strength) if mode == "detail" else DetailLook()
        error = bend = swing = inside = 0.0
        with free_cloth(bundle, ramp):
            for r, truth in zip(records, truths):  # a clip in the database (the paper's validation) may not retrieve itself
                own = names.index(r.name) if r.name in names else None
                anim = animator.animate(r.motion, mode=mode, detail=look, swing=swing_of(label), body=r.dressed,
                                        allow_outside=True, exclude_sequence=own)
                pred = anim.vertices.astype(np.float64)
                inside += anim.penetration.inside_before * len(pred)  # the product path pushes out: what it had to
                error += M.pve_mm(pred, truth) * len(pred)
                bend += float(M.cloth_energies(pred, rest, topo)[1].sum())
                swing += hem_swing(pred, r.motion, hem) * len(pred)
        return {"pve_mm": error / frames, "sharpness": bend / max(truth_bend, 1e-30),
                "hem_swing": swing / max(truth_swing, 1e-30), "penetration_pct": 100.0 * inside / frames}

    candidates = {label: measure(label) for label in tqdm(labels, desc="auto mode", unit="mode", disable=not progress)}
    # then the first pick with its swing restored, each gain a candidate of its own (the criterion
    # picks again among all: a gain wins where its swing closes the gap within the allowance)
    first = pick_auto_mode(candidates, config)
    for gain in tqdm(SWING_GAINS, desc="swing gain", unit="gain", disable=not progress):
        candidates[swing_label(first, gain)] = measure(swing_label(first, gain))
    return repick({"sequences": len(records), "frames": frames, "fold_follow": FOLD_FOLLOW,
                   "swing_half_life_s": HALF_LIFE_S, "candidates": candidates,
                   "criterion": "the most plausible (hypot(ln sharpness, ln hem swing)) within the allowance x the most "
                                "accurate PVE and the penetration allowance x its cloth inside the body"}, config)


def repick(auto: dict, config: AutoConfig) -> dict:
    """A recorded calibration (``bundle.json``'s ``auto``) picked again under ``config``'s
    allowances: the candidates' numbers stand, only the choice among them moves."""
    mode, detail_base, detail_strength = pick_auto_and_detail(auto["candidates"], config)
    return {**auto, "mode": mode, "detail_base": detail_base, "detail_strength": detail_strength,
            "residual_free_mm": pick_free_cloth(auto["candidates"], config),
            "swing_gain": swing_of(pick_auto_mode(auto["candidates"], config)), **config.limits()}


def describe_auto(auto: dict) -> str:
    """One line on a calibration (``bundle.json``'s ``auto``): the choice, the detail mode's setting
    and every candidate's numbers."""
    detail = f"x{auto['detail_strength']:g} on the {auto['detail_base']}"
    if auto.get("swing_gain", 1.0) != 1.0:
        detail += f"; the free cloth's swing x{auto['swing_gain']:g}"
    if auto.get("residual_free_mm"):
        detail += f"; the residual on free cloth {auto['residual_free_mm'][0]:g}-{auto['residual_free_mm'][1]:g} mm"
    allowance = f"the most plausible within {100 * (auto['allowance'] - 1):.0f} % of the most accurate PVE" \
        if "allowance" in auto else ""
    if allowance and "penetration_allowance" in auto:
        allowance += (f" and {100 * (auto['penetration_allowance'] - 1):.0f} % of its cloth inside the body "
                      f"(or {auto.get('penetration_floor_pct', 0):g} % of the vertices)")
    allowance += "; " if allowance else ""
    return (f"auto mode: {auto['mode']} ({allowance}the detail mode's folds {detail}; on {auto['sequences']} validation clips: "
            + "; ".join(f"{m} {c['pve_mm']:.2f} mm, sharpness {c['sharpness']:.2f}, hem swing {c['hem_swing']:.2f}"
                        + (f", {c['penetration_pct']:.2f} % inside" if "penetration_pct" in c else "")
                        for m, c in auto["candidates"].items()) + ")")
