"""The auto mode: its criterion on hand-made numbers, its calibration against the evaluation's
own PVE, and that auto runs the calibrated mode in every path (offline, causal, streamed)."""

import json
import math
import shutil
from dataclasses import replace

import numpy as np
import pytest

from hrr_garment.artifacts.auto_calibration import UNCALIBRATED, AutoCalibration
from hrr_garment.artifacts.manifest_entries import BodiesEntry
from hrr_garment.eval.auto_criterion import (
    DEFAULT_BODY_PVE,
    DETAIL_CANDIDATES,
    DETAIL_STRENGTHS,
    SWING_GAINS,
    AutoSettings,
    candidate_setting,
    detail_label,
    free_cloth_label,
    pick_auto_and_detail,
    pick_auto_mode,
    pick_free_cloth,
    plausibility_gap,
    repick,
    swing_label,
    swing_of,
)
from hrr_garment.eval.auto_mode import calibrate_auto_mode, free_cloth
from hrr_garment.eval.auto_outdated import lacks_default_body, swing_unmeasured
from hrr_garment.motion.synth import synthesize
from hrr_garment.settings import SettingsError


def _c(pve, sharpness, swing):
    return {"pve_mm": pve, "sharpness": sharpness, "hem_swing": swing}


def test_plausibility_gap_weighs_too_smooth_and_too_sharp_alike():
    assert plausibility_gap(1.0, 1.0) == 0.0
    assert (
        plausibility_gap(0.5, 1.0) == pytest.approx(plausibility_gap(2.0, 1.0)) == pytest.approx(math.log(2))
    )
    assert plausibility_gap(0.9, 0.25) == pytest.approx(math.hypot(math.log(0.9), math.log(4)))  # both count
    assert plausibility_gap(0.8, 0.7) < plausibility_gap(
        0.6, 0.7
    )  # a gain in one counts while the other lags
    assert plausibility_gap(0.0, 1.0) == math.inf


@pytest.mark.parametrize(
    "candidates, expected",
    [
        # the sharper mode is within 5 % (the default allowance) of the most accurate: it is chosen
        (
            {
                "hybrid": _c(30.0, 0.13, 0.60),
                "residual": _c(30.3, 0.16, 0.63),
                "detail": _c(30.8, 0.40, 0.63),
            },
            "detail",
        ),
        # 6 % worse is too much, however sharp: the most plausible of the rest
        (
            {
                "hybrid": _c(30.0, 0.13, 0.60),
                "residual": _c(30.6, 0.16, 0.63),
                "detail": _c(31.8, 0.90, 0.95),
            },
            "residual",
        ),
        # the most accurate need not be the hybrid, and the allowance is measured from it
        (
            {
                "hybrid": _c(30.5, 0.13, 0.60),
                "residual": _c(30.0, 0.16, 0.63),
                "detail": _c(30.8, 0.40, 0.63),
            },
            "detail",
        ),
        # equally plausible: the cheaper mode
        ({"hybrid": _c(30.0, 0.50, 0.60), "detail": _c(30.0, 2.0, 0.60)}, "hybrid"),
        # too sharp counts against a mode as much as too smooth
        ({"hybrid": _c(30.0, 0.50, 0.90), "detail": _c(30.5, 3.0, 0.95)}, "hybrid"),
    ],
)
def test_the_criterion_takes_the_most_plausible_of_the_accurate(candidates, expected):
    assert pick_auto_mode(candidates) == expected
    assert pick_auto_mode(candidates, AutoSettings(allowance=1.0)) == min(
        candidates, key=lambda m: (candidates[m]["pve_mm"], list(candidates).index(m))
    )


def test_a_recorded_calibration_is_picked_again_under_another_allowance():
    candidates = {"hybrid": _c(30.0, 0.13, 0.60), "residual": _c(30.6, 0.16, 0.63), R10: _c(31.2, 0.90, 0.95)}
    auto = AutoCalibration.parse(
        {
            "mode": "residual",
            "detail_base": "regression",
            "detail_strength": 1.0,
            "allowance": 1.03,
            "sequences": 3,
            "frames": 90,
            "candidates": candidates,
        }
    )
    wider = repick(auto, AutoSettings(allowance=1.05))  # the folds' 4 % fit the default's 5 %
    assert (wider.mode, wider.allowance, wider.candidates) == ("detail", 1.05, candidates)
    assert (
        repick(wider, AutoSettings(allowance=1.03)).mode == "residual" and auto.mode == "residual"
    )  # the record stays


def test_a_candidate_with_more_cloth_inside_the_body_is_not_the_default():
    """The residual's swing is another simulation's cloth: where it puts more than the penetration
    allowance (1.1 x) of the most accurate candidate's vertices inside the body, the folds on the
    regression are chosen instead; a calibration recorded without the numbers is picked without them."""
    candidates = {
        "hybrid": {**_c(30.0, 0.13, 0.60), "penetration_pct": 3.0},
        R10: {**_c(30.9, 0.90, 0.80), "penetration_pct": 3.3},
        RR10: {**_c(31.0, 0.90, 0.95), "penetration_pct": 3.9},
    }
    assert pick_auto_mode(candidates) == R10
    assert pick_auto_mode(candidates, AutoSettings(penetration_allowance=1.5)) == RR10
    candidates[R10]["penetration_pct"] = 3.31  # 1.103 x: over too
    assert pick_auto_mode(candidates) == "hybrid"
    recorded = {k: {m: v for m, v in c.items() if m != "penetration_pct"} for k, c in candidates.items()}
    assert pick_auto_mode(recorded) == RR10
    small = {k: {**c, "penetration_pct": c["penetration_pct"] / 10} for k, c in candidates.items()}
    assert (
        pick_auto_mode(small) == RR10
    )  # all under the 1 % floor: the push-out's to take, not a reason to lose swing
    assert pick_auto_mode(small, AutoSettings(penetration_floor_pct=0.0)) == "hybrid"
    with pytest.raises(SettingsError, match="penetration_allowance"):
        AutoSettings(penetration_allowance=0.5)


def test_the_allowance_holds_on_the_default_bodys_clips_as_well():
    """A model across bodies: a candidate within the allowance on all the validation clips but not on
    the default body's alone is not the default; numbers recorded without them pick as before."""
    candidates = {
        "hybrid": {**_c(30.0, 0.13, 0.60), DEFAULT_BODY_PVE: 30.0},
        R10: {**_c(31.2, 0.90, 0.90), DEFAULT_BODY_PVE: 31.8},  # 4 % on all, 6 % on the default body
        RR8: {**_c(31.0, 0.70, 0.80), DEFAULT_BODY_PVE: 31.2},
    }
    assert pick_auto_mode(candidates) == RR8
    assert pick_auto_mode(candidates, AutoSettings(allowance=1.06)) == R10
    recorded = {k: {m: v for m, v in c.items() if m != DEFAULT_BODY_PVE} for k, c in candidates.items()}
    assert pick_auto_mode(recorded) == R10
    bodies = {"range": {"bodies": 12}, "default": None}
    auto = replace(UNCALIBRATED, candidates=recorded)
    across = BodiesEntry.parse(bodies, "bodies")
    assert lacks_default_body(auto, across)
    assert not lacks_default_body(replace(auto, default_body_sequences=0), across)
    assert not lacks_default_body(auto, None)  # a model of the mannequin alone
    assert not lacks_default_body(
        auto, BodiesEntry.parse({**bodies, "default": {"name": "hero"}}, "bodies")
    )  # of one body


R8, R10, RR8, RR10 = (
    detail_label(b, s)
    for b, s in (("regression", 0.8), ("regression", 1.0), ("residual", 0.8), ("residual", 1.0))
)


@pytest.mark.parametrize(
    "pves, expected",
    [
        (
            (27.0, 27.2, 27.7, 27.8, 27.9, 28.2),
            ("detail", "regression", 1.0),
        ),  # x1 on the regression within; on the residual not
        ((27.0, 27.2, 27.7, 28.0, 27.6, 27.8), ("detail", "residual", 1.0)),  # all within: the most plausible
        (
            (27.0, 27.2, 27.7, 28.0, 27.6, 28.2),
            ("detail", "residual", 0.8),
        ),  # the strongest folds cost too much
        (
            (27.0, 27.2, 28.5, 28.6, 28.7, 28.9),
            ("residual", "residual", 1.0),
        ),  # none within: auto elsewhere, the
    ],
)  # detail mode's setting by the criterion among the detail candidates alone
def test_the_detail_modes_setting_is_chosen_by_the_same_criterion(pves, expected):
    plausibility = [(0.15, 0.6), (0.2, 0.7), (0.73, 0.71), (0.95, 0.72), (0.74, 0.73), (0.96, 0.74)]
    labels = ["hybrid", "residual", R8, R10, RR8, RR10]
    candidates = {
        k: {"pve_mm": p, "sharpness": s, "hem_swing": w} for k, p, (s, w) in zip(labels, pves, plausibility)
    }
    assert pick_auto_and_detail(candidates, AutoSettings(allowance=1.03)) == expected
    for label in (RR8, RR10):  # no residual weight: the regression's
        del candidates[label]
    assert pick_auto_and_detail(candidates, AutoSettings(allowance=1.03))[1] == "regression"
    assert (
        pick_auto_and_detail({"hybrid": candidates["hybrid"]}, AutoSettings(allowance=1.03))[0] == "hybrid"
    )  # no folds: no detail candidate


def test_free_cloth_labels_and_the_models_one_ramp():
    label = free_cloth_label(RR8, (10.0, 40.0))
    assert label == "detail on residual x0.8, free cloth 10-40 mm"
    assert candidate_setting(label) == ("detail", "residual", 0.8, (10.0, 40.0))
    assert candidate_setting("residual") == ("residual", "regression", None, None)
    assert candidate_setting(free_cloth_label("residual", (20, 60))) == (
        "residual",
        "regression",
        None,
        (20.0, 60.0),
    )
    free = free_cloth_label("residual", (10, 40))
    # the picked candidate's ramp where it uses the residual
    candidates = {
        "hybrid": _c(30.0, 0.2, 0.6),
        "residual": _c(30.2, 0.3, 0.7),
        free: _c(30.3, 0.3, 0.75),
        R10: _c(30.4, 0.3, 0.6),
    }
    assert pick_auto_mode(candidates) == free and pick_free_cloth(candidates) == (10.0, 40.0)
    # the detail mode's on the regression: the residual mode's own pick among its candidates
    candidates[R10] = _c(30.4, 0.9, 0.9)
    assert pick_auto_mode(candidates) == R10 and pick_free_cloth(candidates) == (10.0, 40.0)
    candidates["residual"] = _c(30.2, 0.3, 0.8)
    assert pick_free_cloth(candidates) is None
    # the detail setting's where it rides on the residual
    candidates[free_cloth_label(RR10, (20, 60))] = _c(30.5, 0.95, 0.95)
    assert pick_free_cloth(candidates) == (20.0, 60.0)
    assert repick(replace(UNCALIBRATED, candidates=candidates), AutoSettings()).residual_free_mm == (
        20.0,
        60.0,
    )
    assert pick_free_cloth({"hybrid": _c(30.0, 0.2, 0.6)}) is None
    # the detail setting is the picked detail candidate, not the pick among the detail candidates
    # alone (whose allowance, from their own most accurate, can admit one the model does not run)
    candidates = {
        "residual": _c(30.0, 0.3, 0.7),
        R10: _c(31.0, 0.9, 0.8),
        free_cloth_label(RR10, (10, 40)): _c(32.0, 1.0, 1.0),
    }
    assert pick_auto_and_detail(candidates) == ("detail", "regression", 1.0)
    assert pick_free_cloth(candidates) is None  # so the residual mode's own pick: the plain residual


def test_swing_labels_and_the_models_one_gain():
    label = swing_label(free_cloth_label(RR8, (10.0, 40.0)), 1.2)
    assert label == "detail on residual x0.8, free cloth 10-40 mm, swing x1.2"
    assert candidate_setting(label) == ("detail", "residual", 0.8, (10.0, 40.0)) and swing_of(label) == 1.2
    assert swing_of("residual") == 1.0
    candidates = {
        "residual": _c(30.0, 0.3, 0.7),
        RR10: _c(30.5, 0.9, 0.75),
        swing_label(RR10, 1.1): _c(31.0, 0.9, 0.82),
        swing_label(RR10, 1.3): _c(32.0, 0.9, 0.95),
    }
    picked = repick(
        replace(UNCALIBRATED, candidates=candidates), AutoSettings()
    )  # 1.3's swing is nearest the truth's, but over 5 %
    assert (picked.mode, picked.detail_base, picked.detail_strength, picked.swing_gain) == (
        "detail",
        "residual",
        1.0,
        1.1,
    )
    assert repick(replace(UNCALIBRATED, candidates=candidates), AutoSettings(allowance=1.1)).swing_gain == 1.3
    candidates[swing_label(RR10, 1.1)] = _c(
        31.0, 0.9, 1.6
    )  # a gain that overshoots the truth's swing is less plausible
    assert repick(replace(UNCALIBRATED, candidates=candidates), AutoSettings()).swing_gain == 1.0


def test_hrr_train_calibrates_auto_and_it_agrees_with_the_evaluation(trained):
    from hrr_garment.artifacts.manifest import AUTO_CHOICES
    from hrr_garment.data.dataset import GarmentDataset
    from hrr_garment.eval.evaluate import EvaluationSettings, evaluate_modes
    from hrr_garment.inference.animator import Animator
    from hrr_garment.inference.run_settings import DetailLook

    root, data, _ = trained
    auto = AutoCalibration.parse(json.loads((root / "model" / "bundle.json").read_text())["auto"])
    assert auto.mode in AUTO_CHOICES and {candidate_setting(k)[0] for k in auto.candidates} <= set(
        AUTO_CHOICES
    )
    config = AutoSettings(
        allowance=auto.allowance,
        penetration_allowance=auto.penetration_allowance,
        penetration_floor_pct=auto.penetration_floor_pct,
    )
    assert (auto.mode, auto.detail_base, auto.detail_strength) == pick_auto_and_detail(
        auto.candidates, config
    )
    animator = Animator.load(root / "model")
    assert animator.bundle.auto_mode == auto.mode
    ds = GarmentDataset(data)
    records = [ds.sequence(n) for n in ds.splits["val"]]
    again = calibrate_auto_mode(animator, records, progress=False)
    for mode, c in auto.candidates.items():  # deterministic
        assert again.candidates[mode] == pytest.approx(c)
    # the same PVE as hrr-eval's on these clips (its own path: every metric, the single simulation)
    pve = evaluate_modes(animator, records, EvaluationSettings(("hybrid",), progress=False))[
        "hybrid"
    ].metrics["pve_mm"]
    assert again.candidates["hybrid"]["pve_mm"] == pytest.approx(pve, rel=1e-6)
    for c in again.candidates.values():
        assert (
            c["pve_mm"] > 0 and c["sharpness"] > 0 and c["hem_swing"] > 0 and 0 <= c["penetration_pct"] <= 100
        )
    inside = [animator.animate(r.motion, mode="hybrid", body=r.dressed, allow_outside=True) for r in records]
    expected = (
        100
        * sum(a.penetration.inside_before * len(a.vertices) for a in inside)
        / sum(len(a.vertices) for a in inside)
    )
    assert again.candidates["hybrid"]["penetration_pct"] == pytest.approx(expected)
    # with a residual weight the detail mode is measured on both bases at every strength, each as the mode
    # runs it
    bundle = animator.bundle
    bundle.manifest = replace(bundle.manifest, residual=replace(bundle.manifest.residual, weight=0.7))
    both = calibrate_auto_mode(animator, records[:1], progress=False)
    assert set(both.candidates) >= set(DETAIL_CANDIDATES)
    for label, (base, strength) in DETAIL_CANDIDATES.items():
        pred = animator.animate(records[0].motion, mode="detail", detail=DetailLook(base, strength)).vertices
        assert both.candidates[label]["pve_mm"] == pytest.approx(
            float(np.linalg.norm(pred - records[0].garment, axis=-1).mean()) * 1000, rel=1e-5
        )
    pves = [
        both.candidates[detail_label(base, s)]["pve_mm"]
        for base in ("regression", "residual")
        for s in DETAIL_STRENGTHS
    ]
    assert len(set(pves)) == len(pves)  # each setting changes the output
    # ... and every candidate that borrows from the matches (the residual, the folds) again on free
    # cloth, each ramp as the bundle runs it
    from hrr_garment.artifacts.free_cloth import FREE_CLOTH_RAMPS_MM

    free = [k for k in both.candidates if candidate_setting(k)[3] is not None]
    assert len(free) == len(FREE_CLOTH_RAMPS_MM) * (1 + 2 * len(DETAIL_STRENGTHS)) and both.folds_free_cloth
    for label in free:
        mode, base, strength, ramp = candidate_setting(label)
        with free_cloth(animator.bundle, ramp):
            look = DetailLook(base, strength) if mode == "detail" else DetailLook()
            pred = animator.animate(records[0].motion, mode=mode, detail=look).vertices
        assert both.candidates[label]["pve_mm"] == pytest.approx(
            float(np.linalg.norm(pred - records[0].garment, axis=-1).mean()) * 1000, rel=1e-5
        )
    assert animator.bundle.residual_nodes is None and animator.bundle.fold_weights is None  # left as it was


def test_a_wider_allowance_that_moves_the_first_pick_asks_for_its_swing_gains():
    """The swing gains were measured on the first pick only: a pick that moves has none recorded."""
    accurate, sharp = _c(30.0, 0.2, 0.6), _c(32.0, 0.9, 0.7)
    candidates = {"hybrid": accurate, RR10: sharp}
    candidates |= {swing_label("hybrid", g): _c(30.0 + g / 10, 0.2, 0.6 * g) for g in SWING_GAINS}
    auto = replace(UNCALIBRATED, candidates=candidates)
    assert not swing_unmeasured(
        auto, AutoSettings()
    )  # 5 %: the detail mode is over, hybrid's gains are there
    assert swing_unmeasured(auto, AutoSettings(allowance=1.1))  # 10 %: the detail mode is the first pick
    candidates |= {swing_label(RR10, g): _c(32.0, 0.9, 0.7 * g) for g in SWING_GAINS}
    assert not swing_unmeasured(replace(auto, candidates=candidates), AutoSettings(allowance=1.1))


def test_hrr_train_picks_auto_again_when_its_allowance_changes(trained, tmp_path):
    """The candidates' numbers stand: another allowance re-picks from them, without animating again."""
    from hrr_garment.eval.auto_criterion import AutoSettings
    from hrr_garment.pipeline.auto_stage import calibrate_auto

    root, data, _ = trained
    shutil.copytree(root / "model", tmp_path / "model")
    before = AutoCalibration.parse(json.loads((tmp_path / "model" / "bundle.json").read_text())["auto"])
    widest = calibrate_auto(tmp_path / "model", data, progress=False, config=AutoSettings(allowance=2.0))
    recorded = json.loads((tmp_path / "model" / "bundle.json").read_text())["auto"]
    assert (
        recorded == widest.to_dict() and AutoCalibration.parse(recorded) == widest and widest.allowance == 2.0
    )
    assert all(widest.candidates[k] == c for k, c in before.candidates.items())
    # what was added: the swing gains of the new first pick (the pick without a gain), where it moved
    first = pick_auto_mode(
        {k: c for k, c in before.candidates.items() if swing_of(k) == 1.0}, AutoSettings(allowance=2.0)
    )
    assert set(widest.candidates) == set(before.candidates) | {swing_label(first, g) for g in SWING_GAINS}
    c = widest.candidates
    accurate = min(c, key=lambda m: c[m]["pve_mm"])
    eligible = [
        m
        for m in c
        if c[m]["pve_mm"] <= 2.0 * c[accurate]["pve_mm"]
        and c[m]["penetration_pct"] <= max(1.1 * c[accurate]["penetration_pct"], 1.0) + 1e-9
    ]
    most_plausible = min(plausibility_gap(c[m]["sharpness"], c[m]["hem_swing"]) for m in eligible)
    picked = (
        widest.mode if widest.mode != "detail" else detail_label(widest.detail_base, widest.detail_strength)
    )
    if widest.residual_free_mm and (widest.mode == "residual" or widest.detail_base == "residual"):
        picked = free_cloth_label(picked, widest.residual_free_mm)
    elif widest.mode == "detail" and widest.folds_free_mm:  # the folds alone on free cloth
        picked = free_cloth_label(picked, widest.folds_free_mm)
    if widest.swing_gain != 1.0:
        picked = swing_label(picked, widest.swing_gain)
    assert plausibility_gap(c[picked]["sharpness"], c[picked]["hem_swing"]) == most_plausible


@pytest.mark.parametrize("before", ["penetration", "fold_follow", "folds_free_cloth"])
def test_a_calibration_recorded_before_is_made_again(trained, tmp_path, before):
    """Bundles calibrated before the criterion counted the cloth inside the body, before the
    detail mode's folds followed in time or before the folds were measured on free cloth, are
    calibrated again by hrr-train, not re-picked from numbers that lack it or measured another
    detail mode."""
    from hrr_garment.artifacts.typed_manifest import update_manifest
    from hrr_garment.inference.fold_track import FOLD_FOLLOW
    from hrr_garment.pipeline.auto_stage import calibrate_auto

    root, data, _ = trained
    shutil.copytree(root / "model", tmp_path / "model")
    auto = AutoCalibration.parse(json.loads((tmp_path / "model" / "bundle.json").read_text())["auto"])
    assert auto.fold_follow == FOLD_FOLLOW
    if before == "penetration":
        old = {k: {m: v for m, v in c.items() if m != "penetration_pct"} for k, c in auto.candidates.items()}
        update_manifest(tmp_path / "model", auto=replace(auto, candidates=old))
    else:
        # numbers of another detail mode (here: made up), recorded without the following (or the folds'
        # ramps)
        old = {k: {**c, "pve_mm": 999.0} for k, c in auto.candidates.items()}
        update_manifest(tmp_path / "model", auto=replace(auto, candidates=old, **{before: None}))
        assert before not in json.loads((tmp_path / "model" / "bundle.json").read_text())["auto"]
    again = calibrate_auto(tmp_path / "model", data, progress=False)
    assert again.fold_follow == FOLD_FOLLOW and again.folds_free_cloth
    assert again.mode == auto.mode and set(again.candidates) == set(auto.candidates)
    for label, c in auto.candidates.items():
        assert again.candidates[label] == pytest.approx(c)


def test_the_folds_on_free_cloth_run_as_the_bundle_records_them(trained, tmp_path):
    """bundle.json ``auto.folds_free_mm``: a ramp beyond every vertex's hang leaves the regression's
    shape (no folds), one below all of them the folds everywhere, as without a ramp."""
    from hrr_garment.artifacts.typed_manifest import update_manifest
    from hrr_garment.inference.animator import Animator
    from hrr_garment.inference.run_settings import DetailLook

    root, _, _ = trained
    copy = tmp_path / "model"
    shutil.copytree(root / "model", copy)
    motion = synthesize("walk", 1.0, seed=5)
    look = DetailLook("regression", 1.0)
    runs = {}
    for ramp in (None, [5000.0, 6000.0], [-6000.0, -5000.0]):
        update_manifest(
            copy,
            auto=AutoCalibration.parse(
                {"mode": "detail", "detail_base": "regression", "detail_strength": 1.0, "folds_free_mm": ramp}
            ),
        )
        animator = Animator.load(copy)
        runs[None if ramp is None else ramp[0]] = animator.animate(
            motion, mode="detail", detail=look, push_out=False
        ).vertices
    regression = animator.animate(motion, mode="regression", push_out=False).vertices
    assert np.abs(runs[None] - regression).max() > 1e-4  # the folds change the shape ...
    assert np.allclose(runs[5000.0], regression, atol=1e-6)  # ... not on cloth that is nowhere free
    assert np.array_equal(runs[-6000.0], runs[None])


@pytest.mark.parametrize(
    "chosen, base, strength",
    [("detail", "regression", 0.6), ("detail", "residual", 1.0), ("hybrid", "regression", 0.8)],
)
def test_auto_runs_the_calibrated_mode_everywhere(trained, tmp_path, chosen, base, strength):
    from hrr_garment.artifacts.typed_manifest import read_manifest, update_manifest
    from hrr_garment.inference.animator import Animator

    root, _, _ = trained
    copy = tmp_path / "model"
    shutil.copytree(root / "model", copy)
    residual = read_manifest(copy).residual
    update_manifest(
        copy,
        auto=AutoCalibration.parse({"mode": chosen, "detail_base": base, "detail_strength": strength}),
        residual=replace(residual, weight=0.7),
    )
    animator = Animator.load(copy)
    assert animator.bundle.detail_base == base and animator.bundle.detail_strength == strength
    motion = synthesize("walk", 1.0, seed=5)
    default = animator.animate(motion, push_out=False)
    named = animator.animate(motion, mode=chosen, push_out=False)
    assert default.settings["mode"] == chosen and np.array_equal(default.vertices, named.vertices)
    causal = animator.animate(motion, mode=chosen, push_out=False, causal=True)
    stream = animator.stream(push_out=False)
    assert stream.mode == chosen
    streamed = np.stack([stream.push(motion.slice(t, t + 1)) for t in range(motion.num_frames)])
    assert np.allclose(streamed, causal.vertices, atol=1e-5)


def test_a_model_without_auto_runs_the_hybrid(trained, tmp_path):
    from hrr_garment.artifacts.typed_manifest import update_manifest
    from hrr_garment.inference.animator import Animator

    root, _, _ = trained
    copy = tmp_path / "model"
    shutil.copytree(root / "model", copy)
    update_manifest(copy, auto=None)
    animator = Animator.load(copy)
    assert animator.resolve().mode == "hybrid"
    motion = synthesize("walk", 0.5, seed=6)
    assert np.array_equal(
        animator.animate(motion, push_out=False).vertices,
        animator.animate(motion, mode="hybrid", push_out=False).vertices,
    )


def test_a_candidate_measured_as_nan_is_described_not_raised():
    """A NaN a candidate measured (a diverged model) is stored as null (bundle.json is JSON); the line
    hrr-train prints says so instead of failing."""
    from hrr_garment.artifacts.auto_calibration import AutoCalibration
    from hrr_garment.eval.auto_criterion import describe_auto

    auto = AutoCalibration.from_report(
        {
            "mode": "hybrid",
            "detail_base": "regression",
            "detail_strength": 1.0,
            "sequences": 2,
            "candidates": {"hybrid": {"pve_mm": float("nan"), "sharpness": 0.5, "hem_swing": 0.9}},
        },
        "auto",
    )
    assert "hybrid n/a mm, sharpness 0.50, hem swing 0.90" in describe_auto(auto)
