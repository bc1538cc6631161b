"""The detail mode: the regression's shape plus simulated folds, the high spatial frequencies of
the database's frames (the fold store), chosen frame by frame by a playhead (the fold track)."""

from dataclasses import replace
from functools import partial

import numpy as np
import pytest

from hrr_garment.artifacts import fold_codec
from hrr_garment.artifacts.auto_calibration import AutoCalibration
from hrr_garment.artifacts.folds import FOLD_ENCODING, FoldStore
from hrr_garment.artifacts.manifest import migrate_manifest
from hrr_garment.garment.smoothing import high_frequencies, mean_operator
from hrr_garment.garment.templates import make_garment
from hrr_garment.inference.detail import add_folds
from hrr_garment.inference.fold_track import (
    FoldTrack,
    causal_proposals,
    follow_folds,
    follow_over_time,
    offline_proposals,
    track_folds,
)
from hrr_garment.inference.frame_path import FramePath
from hrr_garment.inference.run_settings import DetailLook, RunSettings
from hrr_garment.motion.frame import from_body_frame, to_body_frame
from hrr_garment.motion.synth import synthesize
from hrr_garment.motion.windows import covering_windows


@pytest.fixture(scope="module")
def skirt():
    garment = make_garment("skirt", 300)
    return garment, mean_operator(garment.faces, garment.num_vertices)


def _rotation(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def test_high_frequencies_keep_folds_and_drop_shape(skirt, rng):
    garment, mean = skirt
    frames = np.repeat(garment.vertices[None], 2, 0).astype(np.float64)
    assert np.allclose(
        high_frequencies(frames + [0.05, -0.02, 0.01], mean, 1), high_frequencies(frames, mean, 1)
    )
    folds = rng.normal(0.0, 0.003, frames.shape)  # per-vertex noise: the highest frequency, mostly kept
    kept = np.sum(high_frequencies(folds, mean, 3) * folds) / np.sum(folds * folds)
    assert 0.6 < kept < 1.1
    rot = _rotation(0.7)  # commutes with rotations: the same in the body frame and the world
    assert np.allclose(high_frequencies(frames @ rot.T, mean, 2), high_frequencies(frames, mean, 2) @ rot.T)


@pytest.mark.parametrize("passes", [1, 3])
def test_the_int8_fold_store_keeps_each_frame_within_half_a_step(skirt, rng, passes):
    garment, mean = skirt
    sequences = [
        garment.vertices[None] + rng.normal(0, 0.004, (n, garment.num_vertices, 3)) for n in (5, 1, 7)
    ]
    store = FoldStore.build(sequences, mean, passes, encoding="int8")
    assert store.levels.dtype == np.int8 and list(store.lengths) == [5, 1, 7] and store.passes == passes
    exact = np.concatenate([high_frequencies(s, mean, passes) for s in sequences])
    one = np.stack([np.arange(13), np.zeros(13, int)], 1)
    got = store.folds(one, np.array([[1.0, 0.0]] * 13))
    assert np.all(np.abs(got - exact) <= store.scale[:, None, None] / 2 + 1e-9)
    assert np.abs(got - exact).max() < 0.01 * np.abs(exact).max()
    # weighted rows: a linear mix of the stored frames
    mixed = store.folds(np.array([[store.rows(2, 3), store.rows(0, 4)]]), np.array([[0.25, 0.75]]))
    assert np.allclose(mixed[0], 0.25 * got[5 + 1 + 3] + 0.75 * got[4])
    with pytest.raises(IndexError):
        store.rows(1, 1)  # sequence 1 has one frame


def test_the_nf4_fold_store_rounds_each_value_to_its_nearest_level(skirt, rng):
    """Four bits a value: every value within half the gap between the two levels around it (times
    its block's scale), each block's largest value exact, 0 kept exact, at about half int8's bytes."""
    garment, mean = skirt
    sequences = [
        garment.vertices[None] + rng.normal(0, 0.004, (n, garment.num_vertices, 3)) for n in (5, 1, 7)
    ]
    store = FoldStore.build(sequences, mean, 1)
    int8 = FoldStore.build(sequences, mean, 1, encoding="int8")
    assert store.encoding == FOLD_ENCODING == "nf4" and store.num_vertices == garment.num_vertices
    assert store.levels.nbytes + store.scale.nbytes < 0.55 * (int8.levels.nbytes + int8.scale.nbytes)
    exact = np.concatenate([high_frequencies(s, mean, 1) for s in sequences]).reshape(13, -1)
    got = store.frames(np.arange(13)).reshape(13, -1)
    blocks = fold_codec.blocks_of(exact.shape[1])
    padded = np.zeros((13, blocks * fold_codec.BLOCK))
    padded[:, : exact.shape[1]] = exact
    scale = np.abs(padded.reshape(13, blocks, -1)).max(axis=2)
    per_value = np.repeat(scale, fold_codec.BLOCK, axis=1)[:, : exact.shape[1]]
    widest_gap = np.diff(fold_codec.CODEBOOK).max()
    assert np.all(np.abs(got - exact) <= per_value * (widest_gap / 2 + 1e-3))  # float16 scales: 1e-3
    biggest = np.abs(exact).argmax(axis=1)
    assert np.allclose(got[np.arange(13), biggest], exact[np.arange(13), biggest], rtol=1e-3)
    # on normal values the levels round better than even ones would: RMS error under a tenth
    assert np.sqrt(np.mean((got - exact) ** 2)) < 0.1 * np.sqrt(np.mean(exact**2))
    codes, zero_scale = fold_codec.encode(np.zeros((2, 7)))
    assert np.array_equal(fold_codec.decode(codes, zero_scale, 7), np.zeros((2, 7)))
    assert np.allclose(
        store.folds(np.array([[2, 4]]), np.array([[0.5, 2.0]]))[0].ravel(), 0.5 * got[2] + 2.0 * got[4]
    )


def test_the_fold_store_refuses_inconsistent_arrays():
    detail = np.zeros((4, 10, 3), np.int8)
    with pytest.raises(ValueError, match="int8"):
        FoldStore(detail.astype(np.float32), np.ones(4), [0, 4])
    with pytest.raises(ValueError, match="offsets"):
        FoldStore(detail, np.ones(4), [0, 3])
    with pytest.raises(ValueError, match="scales"):
        FoldStore(detail, np.array([1.0, np.nan, 1.0, 1.0]), [0, 4])
    with pytest.raises(ValueError, match="encoding"):
        FoldStore(detail, np.ones(4), [0, 4], encoding="int4")
    codes = np.zeros((4, fold_codec.blocks_of(30), fold_codec.BLOCK // 2), np.uint8)
    FoldStore(codes, np.ones((4, 1)), [0, 4], encoding="nf4", vertices=10)
    with pytest.raises(ValueError, match="number of vertices"):
        FoldStore(codes, np.ones((4, 1)), [0, 4], encoding="nf4")
    with pytest.raises(ValueError, match="nf4 fold codes of 40 vertices"):
        FoldStore(codes, np.ones((4, 1)), [0, 4], encoding="nf4", vertices=40)
    with pytest.raises(ValueError, match="scales"):
        FoldStore(codes, np.ones(4), [0, 4], encoding="nf4", vertices=10)


def test_folds_replace_the_regressions_own_and_commute_with_a_rigid_motion(skirt, rng):
    garment, mean = skirt
    regression = garment.vertices[None].astype(np.float64) + rng.normal(0, 0.01, (2, garment.num_vertices, 3))
    folds = high_frequencies(regression + rng.normal(0, 0.003, regression.shape), mean, 1)
    assert np.allclose(add_folds(regression, folds, mean, 1, strength=0.0), regression, atol=1e-6)
    # the regression's own high frequencies in, nothing changes; strength scales the change linearly
    assert np.allclose(
        add_folds(regression, high_frequencies(regression, mean, 1), mean, 1), regression, atol=1e-6
    )
    full = add_folds(regression, folds, mean, 1, strength=1.0) - regression
    assert np.allclose(
        add_folds(regression, folds, mean, 1, strength=0.5) - regression, 0.5 * full, atol=1e-6
    )
    rot, shift = _rotation(0.7), np.array([1.0, 0.0, 2.0])
    moved = add_folds(regression @ rot.T + shift, folds @ rot.T, mean, 1)
    assert np.allclose(
        moved, add_folds(regression, folds, mean, 1).astype(np.float64) @ rot.T + shift, atol=1e-5
    )


def test_folds_on_free_cloth_are_weighted_per_vertex(skirt, rng):
    """The free-cloth weights scale each vertex's fold term: 0 keeps the regression's shape there,
    1 the folds as they come, and the term is linear in them."""
    garment, mean = skirt
    regression = garment.vertices[None].astype(np.float64) + rng.normal(0, 0.01, (2, garment.num_vertices, 3))
    folds = high_frequencies(regression + rng.normal(0, 0.003, regression.shape), mean, 1)
    full = add_folds(regression, folds, mean, 1) - regression
    weights = rng.uniform(0, 1, (garment.num_vertices, 1)).astype(np.float32)
    weights[::3] = 0.0
    weighted = add_folds(regression, folds, mean, 1, weights=weights) - regression
    assert np.allclose(weighted, weights * full, atol=1e-6)
    assert np.allclose(weighted[:, ::3], 0.0, atol=1e-6) and np.abs(full[:, ::3]).max() > 1e-4
    assert np.allclose(
        add_folds(regression, folds, mean, 1, weights=np.ones_like(weights)) - regression, full, atol=1e-6
    )


def test_folds_that_would_overstretch_an_edge_are_taken_back_and_others_kept(skirt, rng):
    """Folds from another simulation may tear this shape; the limit takes back only what passes
    FOLD_MAX_STRAIN x the rest length (where the regression's edge is shorter)."""
    from hrr_garment.inference.collision import EdgeLimits
    from hrr_garment.inference.detail import FOLD_MAX_STRAIN

    garment, mean = skirt
    limits = EdgeLimits.of(garment.faces, garment.vertices)
    regression = np.repeat(garment.vertices[None].astype(np.float64), 2, 0)
    gentle = high_frequencies(regression + rng.normal(0, 0.001, regression.shape), mean, 1)
    violent = gentle.copy()
    violent[1, 7] += [0.0, 0.3, 0.0]  # one vertex of frame 1 thrown 30 cm: its edges many times their length
    before = limits.lengths(add_folds(regression, violent, mean, 1)) / limits.rest_length
    assert before[1].max() > 3 and before[0].max() < FOLD_MAX_STRAIN
    kept = add_folds(regression, gentle, mean, 1, limits=limits)
    np.testing.assert_array_equal(
        kept, add_folds(regression, gentle, mean, 1)
    )  # nothing to take back: untouched
    limited = add_folds(regression, violent, mean, 1, limits=limits)
    strain = limits.lengths(limited.astype(np.float64)) / limits.rest_length
    assert strain.max() <= FOLD_MAX_STRAIN * 1.01
    np.testing.assert_array_equal(
        limited[0], add_folds(regression, violent, mean, 1)[0]
    )  # a frame within it stays


OFFSETS = np.array([0, 100, 130, 400])  # three database sequences of 100, 30 and 270 frames


def test_the_track_follows_agreeing_proposals_forward_without_a_switch():
    proposals = np.array([[2, 50 + t + (t % 3) - 1] for t in range(40)])  # sequence 2, wobbling by a frame
    rows, weights = track_folds(proposals, OFFSETS)
    assert np.array_equal(
        rows[:, 0], OFFSETS[2] + 49 + np.arange(40)
    )  # from the first proposal, a frame on per frame
    assert np.array_equal(weights[:, 0], np.ones(40))


def test_the_track_jumps_after_hold_frames_of_disagreement_and_fades_the_old_folds_out():
    track = FoldTrack(OFFSETS, hold=4, fade=3)
    steps = [track.step(0, 10 + t) for t in range(5)]  # agreeing with itself
    steps += [track.step(1, 5) for _ in range(10)]  # a proposal elsewhere, the same every frame
    rows = np.array([r for r, _ in steps])
    weights = np.array([w for _, w in steps])
    assert np.allclose(weights.sum(1), 1.0)
    jump = 5 + 4 - 1  # the fourth disagreeing frame
    assert np.array_equal(rows[:jump, 0], np.arange(10, 10 + jump))  # played forward until then
    assert rows[jump, 0] == OFFSETS[1] + 5 and rows[jump, 1] == 10 + jump  # then the proposal, the old fading
    assert np.allclose(weights[jump : jump + 4, 1], [3 / 4, 2 / 4, 1 / 4, 0.0])
    assert np.array_equal(
        rows[jump + 1 : jump + 3, 1], [11 + jump, 12 + jump]
    )  # the old plays on as it fades


def test_the_track_rests_where_the_same_frame_keeps_being_proposed():
    # a body standing still: every window matches the same one, so every frame proposes one frame
    track = FoldTrack(OFFSETS, hold=4, fade=3, rest=4)
    steps = [track.step(2, 50) for _ in range(40)]
    rows = np.array([r for r, _ in steps])
    weights = np.array([w for _, w in steps])
    # it plays on while the proposal might still move, then rests within the slack: no loop back
    assert rows[:, 0].tolist() == [OFFSETS[2] + f for f in (50, 51, 52, 53)] + [OFFSETS[2] + 53] * 36
    assert np.array_equal(weights[:, 0], np.ones(40))  # no jump, so nothing fades
    # and it plays on again, one frame a frame, once the proposals move
    moved = [track.step(2, 54 + t)[0][0] for t in range(5)]
    assert moved == [OFFSETS[2] + f for f in range(54, 59)]


def test_at_the_defaults_a_repeated_proposal_costs_one_jump_back_then_the_track_rests():
    track = FoldTrack(OFFSETS)
    rows = [int(track.step(2, 50)[0][0]) - OFFSETS[2] for _ in range(40)]
    # plays on 8 frames, stops (disagreeing), jumps back after the hold, rests there for good
    assert rows == list(range(50, 58)) + [57] * 3 + [50] * 29


def test_the_track_jumps_where_its_sequence_ends():
    track = FoldTrack(OFFSETS, hold=50)
    rows = [track.step(1, 27)[0][0] for _ in range(2)] + [track.step(0, 3)[0][0] for _ in range(2)]
    assert rows == [OFFSETS[1] + 27, OFFSETS[1] + 28, OFFSETS[1] + 29, 3]  # 29 is its last: then the proposal


def test_proposals_are_each_frames_frame_in_its_match():
    # offline: 8 frames, windows of 5, so 12 windows, window i covering frames i - 4 .. i (the clip's
    # ends repeated); frame t's is its frame in the match of the window centred on it, or near an
    # end the clip's first (4) or last (7) window of its own frames
    source = np.array(
        [[0, 10], [1, 40], [2, 7], [0, 60], [1, 0], [2, 20], [0, 5], [1, 9], [2, 30], [0, 1]] * 2
    )[:12]
    assert offline_proposals(source, 8, 5).tolist() == [
        [1, 0],
        [1, 1],
        [1, 2],
        [2, 22],
        [0, 7],
        [1, 11],
        [1, 12],
        [1, 13],
    ]
    with pytest.raises(ValueError, match="covering_windows"):  # the clip's own windows alone: refused
        offline_proposals(source[:4], 8, 5)
    assert causal_proposals(source[:4], 5).tolist() == [[0, 14], [1, 44], [2, 11], [0, 64]]


@pytest.mark.parametrize("base, strength", [("residual", 1.0), ("regression", None)])
def test_the_detail_mode_is_its_base_plus_the_tracked_simulated_folds(trained, base, strength):
    """The folds ride on the residual mode's latents or on the regression's at a strength, as the
    auto calibration chose (bundle.json auto.detail_base and detail_strength; the regression's and
    0.8 in bundles from before)."""
    from hrr_garment.artifacts.folds import DETAIL_STRENGTH
    from hrr_garment.inference.animator import Animator

    root, _, _ = trained
    animator = Animator.load(root / "model")
    bundle, manifest = animator.bundle, animator.bundle.manifest
    assert bundle.has_residual
    bundle.manifest = replace(
        manifest,
        residual=replace(manifest.residual, weight=0.7),  # a weight the tiny model may not have calibrated
        auto=replace(manifest.auto, detail_base=base, detail_strength=strength),
    )
    assert animator.bundle.detail_base == base
    if base == "regression":  # as version-2 bundles calibrated before the choice read, upgraded
        old = {**bundle.manifest.to_dict(), "format_version": 2, "auto": {"mode": manifest.auto.mode}}
        upgraded = AutoCalibration.parse(migrate_manifest(bundle.folder, old)["auto"])
        bundle.manifest = replace(bundle.manifest, auto=upgraded)
        assert (
            animator.bundle.detail_base == "regression" and animator.bundle.detail_strength == DETAIL_STRENGTH
        )
    store = animator.bundle.folds
    assert store is not None and len(store.lengths) == len(animator.bundle.database.names)
    motion = synthesize("walk", 1.0, seed=3)
    regression = animator.animate(motion, mode="regression", push_out=False).vertices
    shape = animator.animate(motion, mode=base, push_out=False).vertices
    detail = animator.animate(motion, mode="detail", push_out=False)
    retrieval = animator.animate(motion, mode="retrieval", push_out=False)
    assert not detail.retrieved.any() and np.array_equal(detail.match, retrieval.match)
    # the same by hand: the track over the windows' matches, their folds on the base in the body frame
    windows = np.ascontiguousarray(covering_windows(animator.features(motion), animator.window))
    source = FramePath(animator, animator.resolve(mode="detail")).choose(windows).match
    rows, weights = track_folds(offline_proposals(source, motion.num_frames, animator.window), store.offsets)
    local = to_body_frame(shape.astype(np.float64), motion)
    follow = partial(follow_over_time, mean=animator.smoothing)
    expected = from_body_frame(
        add_folds(
            local,
            store.folds(rows, weights),
            animator.smoothing,
            store.passes,
            strength or DETAIL_STRENGTH,
            limits=animator.edge_limits,
            follow=follow,
        ),
        motion,
    )
    assert np.abs(detail.vertices - expected).max() < 1e-4
    assert not np.allclose(detail.vertices, shape, atol=1e-3)
    assert (base == "regression") == np.allclose(shape, regression, atol=1e-5)


def test_a_bundle_before_the_folds_says_how_to_add_them_and_hrr_train_does(trained, tmp_path, capsys):
    import json

    from hrr_garment.artifacts.bundle import BundleError
    from hrr_garment.artifacts.manifest import FOLDS_FILE, content_hash
    from hrr_garment.artifacts.typed_manifest import update_manifest
    from hrr_garment.cli.train import main as train_main
    from hrr_garment.inference.animator import Animator
    from tests.conftest import current_copy, write_meta

    old, stage = current_copy(trained, tmp_path / "model")
    folds = (old / FOLDS_FILE).read_bytes()
    meta = json.loads((old / "bundle.json").read_text())
    del meta["folds"], meta["files"][FOLDS_FILE]
    meta["content_hash"] = content_hash(meta["files"])
    meta["format_version"] = 2  # a bundle written before the folds
    (old / FOLDS_FILE).unlink()
    write_meta(old, meta)
    update_manifest(old, auto=AutoCalibration.parse({**meta["auto"], "mode": "detail"}))
    animator = Animator.load(old)
    assert not animator.supports("detail") and animator.resolve().mode == "hybrid"
    with pytest.raises(BundleError, match="hrr-train --stage codespace"):
        animator.animate(synthesize("walk", 0.5, seed=1), mode="detail")
    with pytest.raises(BundleError, match="no simulated folds"):
        animator.stream(mode="detail")
    # the finished stage is reused (nothing retrained), the folds added as they were, auto calibrated anew
    weights = (old / "motion_encoder.safetensors").read_bytes()
    capsys.readouterr()
    assert train_main(stage) == 0
    assert (
        "(reused)" in capsys.readouterr().out and (old / "motion_encoder.safetensors").read_bytes() == weights
    )
    assert (old / FOLDS_FILE).read_bytes() == folds
    animator = Animator.load(old)
    assert animator.supports("detail") and "detail x0.8" in animator.bundle.auto.candidates


def test_a_damaged_fold_store_is_refused(trained, tmp_path):
    import shutil

    from hrr_garment.artifacts.bundle_loader import BundleError, load_bundle
    from hrr_garment.artifacts.bundle_writer import add_bundle_part
    from hrr_garment.artifacts.manifest import FOLDS_FILE

    root, _, _ = trained
    copy = tmp_path / "model"
    shutil.copytree(root / "model", copy)
    store = load_bundle(copy).folds
    short = {**store.arrays(), "offsets": store.offsets[:-1]}  # one database sequence too few
    add_bundle_part(copy, FOLDS_FILE, short, numpy=True)
    with pytest.raises(BundleError, match="offsets must rise"):
        load_bundle(copy)
    fewer = {
        "detail": store.levels[:, :-1],
        "scale": store.scale[:, :-1],
        "offsets": store.offsets,
    }  # a block short
    add_bundle_part(copy, FOLDS_FILE, fewer, numpy=True)
    with pytest.raises(BundleError, match="vertices"):
        load_bundle(copy)


def test_hrr_animate_runs_the_detail_mode_as_it_is_told(trained, tmp_path, capsys):
    """``--detail-strength`` / ``--detail-base`` set the detail mode's look (with the default mode
    they run it), the output records the setting, and a setting the model cannot run is refused
    before anything is written."""
    import shutil

    from hrr_garment.artifacts.typed_manifest import read_manifest, update_manifest
    from hrr_garment.cli.animate import main as animate_main
    from hrr_garment.data.animation_file import read_animation_h5
    from hrr_garment.inference.animator import Animator
    from hrr_garment.motion.io import save_motion

    root, _, _ = trained
    model = tmp_path / "model"
    shutil.copytree(root / "model", model)
    residual = read_manifest(model).residual
    update_manifest(model, residual=replace(residual, weight=0.7))
    motion = synthesize("walk", 1.0, seed=4)
    clip = tmp_path / "walk.npz"
    save_motion(motion, clip)
    out = tmp_path / "out.h5"
    assert (
        animate_main(
            [
                str(clip),
                "-o",
                str(out),
                "--model",
                str(model),
                "--detail-strength",
                "1.3",
                "--detail-base",
                "residual",
                "--no-collision",
            ]
        )
        == 0
    )
    assert "mode auto = detail, folds x1.3 on the residual" in capsys.readouterr().out
    written = read_animation_h5(out)
    assert written.attrs["detail_strength"] == 1.3 and written.attrs["detail_base"] == "residual"
    animator = Animator.load(model)
    look = DetailLook(base="residual", strength=1.3)
    expected = animator.animate(motion, detail=look, push_out=False)
    assert expected.settings["mode"] == "detail" and np.array_equal(written.vertices, expected.vertices)
    calibrated = animator.animate(motion, mode="detail", push_out=False)
    assert calibrated.settings["detail_strength"] == animator.bundle.detail_strength != 1.3
    assert not np.allclose(calibrated.vertices, expected.vertices, atol=1e-4)
    # a stream keeps the look it was made with, frame by frame as offline causal
    stream = animator.stream(mode="detail", detail=look, push_out=False)
    streamed = np.stack([stream.push(motion.slice(t, t + 1)) for t in range(motion.num_frames)])
    causal = animator.animate(motion, RunSettings(mode="detail", detail=look, push_out=False, causal=True))
    assert np.allclose(streamed, causal.vertices, atol=1e-5)
    from_array = animator.animate(motion, detail=DetailLook("residual", np.float32(1.3)), push_out=False)
    assert from_array.settings["detail_strength"] == pytest.approx(1.3) and isinstance(
        from_array.settings["detail_strength"], float
    )
    for asked in (
        lambda: {"mode": "hybrid", "detail": DetailLook(strength=1.0)},
        lambda: {"tau": 0.1, "detail": DetailLook(base="regression")},
        lambda: {"detail": DetailLook(strength=0.0)},
        lambda: {"detail": DetailLook(base="shape")},
        lambda: {"tau": float("nan")},
        lambda: {"tau": -1.0},
    ):
        with pytest.raises(ValueError):
            animator.animate(motion, push_out=False, **asked())
    with pytest.raises(TypeError, match=r"detail_strength \(now detail=DetailLook\(strength=...\)\)"):
        animator.animate(motion, detail_strength=1.0)

    refused = tmp_path / "refused.h5"
    update_manifest(model, residual=replace(residual, weight=0.0))
    for extra, phrase in (
        (["--detail-strength", "0"], "must be in (0, 2]"),
        (["--detail-strength", "2.5"], "must be in (0, 2]"),
        (["--detail-strength", "1", "--mode", "hybrid"], "mode hybrid does not use them"),
        (["--detail-base", "regression", "--tau", "0.1"], "name the mode"),
        (["--detail-base", "residual"], "residual weight is calibrated to 0"),
    ):
        assert (
            animate_main([str(clip), "-o", str(refused), "--model", str(model), "--no-collision", *extra])
            == 2
        )
        assert phrase in capsys.readouterr().err, extra
        assert not refused.exists()


def _curvature(folds, mean):  # the size of the folds' 1-ring Laplacian
    return np.sqrt((high_frequencies(folds, mean, 1) ** 2).sum(-1).mean(-1))


def test_followed_folds_keep_a_still_pattern_and_calm_a_flickering_one(skirt, rng):
    garment, mean = skirt
    still = np.repeat(high_frequencies(rng.normal(0, 0.003, (1, garment.num_vertices, 3)), mean, 1), 20, 0)
    np.testing.assert_allclose(follow_over_time(still, mean), still, atol=1e-12)  # nothing moves: as they are
    flicker = high_frequencies(
        rng.normal(0, 0.003, (40, garment.num_vertices, 3)), mean, 1
    )  # new folds every frame
    followed = follow_over_time(flicker, mean)
    np.testing.assert_array_equal(followed[0], flicker[0])  # the first frame as it comes
    np.testing.assert_array_equal(follow_over_time(flicker, mean, follow=1.0), flicker)  # 1: no smoothing
    acceleration = [np.linalg.norm(np.diff(x, 2, axis=0), axis=-1).mean() for x in (flicker, followed)]
    assert acceleration[1] < 0.6 * acceleration[0]
    # scaled back to the folds' curvature (the followed ratio: within a few percent once settled)
    ratio = _curvature(followed[10:], mean) / _curvature(flicker[10:], mean)
    assert np.all(np.abs(ratio - 1.0) < 0.15) and abs(ratio.mean() - 1.0) < 0.05


def test_followed_folds_of_a_crowd_are_each_animation_alone(skirt, rng):
    garment, mean = skirt
    a, b = (high_frequencies(rng.normal(0, 0.003, (12, garment.num_vertices, 3)), mean, 1) for _ in range(2))
    alone = [follow_over_time(x, mean) for x in (a, b)]
    states = [None, None]
    together = []
    for t in range(12):
        if t == 5:  # b restarts (a teleport): its state is forgotten, a's kept
            states[1] = None
            alone[1][5:] = follow_over_time(b[5:], mean)
        together.append(follow_folds(np.stack([a[t], b[t]]), states, mean))
    together = np.stack(together, 1)
    np.testing.assert_allclose(together[0], alone[0], atol=1e-12)
    np.testing.assert_allclose(together[1], alone[1], atol=1e-12)
