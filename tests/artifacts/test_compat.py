"""Files written by an older hrr_garment (commit 31b4ef9: bundle.json and out.h5 format 2) load,
upgrade in one place, and animate to the same vertices (tests/fixtures/README.md)."""

import json
import shutil
from functools import partial
from pathlib import Path

import numpy as np

from hrr_garment import Animator, synthesize
from hrr_garment.artifacts.manifest import FORMAT_VERSION
from hrr_garment.artifacts.typed_manifest import update_manifest
from hrr_garment.data.animation_file import read_animation_h5

DATA = Path(__file__).parents[1] / "fixtures"


def _walk():
    return synthesize("walk", seconds=2, seed=3)


def _blended_alike(animator, frames: int, settle: int = 0) -> slice:
    """The frames of an offline animation that blend the windows of the clip's own frames alone, as
    before the clip's ends were repeated past them (f1cbfa3: the first and last W - 1 frames now
    blend all W windows, and a still body's cloth no longer drifts there), less the first
    ``settle`` frames more, where a filter over time (the detail's followed folds) carries the
    start's change on."""
    w = animator.window
    return slice(w - 1 + settle, frames - w + 1)


def test_a_version_2_bundle_loads_and_animates_as_31b4ef9_did(tmp_path, monkeypatch):
    """The detail mode as 31b4ef9 ran it, before its folds were strain-limited and followed in time, and
    before the push-out's strain limit had its slack and its Gauss-Seidel passes (and the causal residual
    before only its departure was inertialized): the same vertices on the frames the limit left, on the others
    within its repair; with the limits, the same frames with no edge past them (tests/inference/test_detail.py
    and test_collision.py test the limits themselves)."""
    import dataclasses

    from hrr_garment.inference import blending, collision, detail, fold_track

    folder = shutil.copytree(DATA / "bundle-31b4ef9", tmp_path / "model")
    animator = Animator.load(folder)
    manifest = animator.bundle.manifest
    assert json.loads((folder / "bundle.json").read_text())["format_version"] == 2
    assert manifest.format_version == FORMAT_VERSION == 5  # upgraded in memory, the file untouched
    assert manifest.gate in ("entropy", "similarity", "distance") and set(manifest.gates) <= {
        "entropy",
        "similarity",
        "distance",
    }
    assert {"memory_seconds", "resonator_hz", "regression_code"} <= set(manifest.codespace.config)
    written = read_animation_h5(DATA / "out-31b4ef9" / "auto.h5")
    monkeypatch.setattr(fold_track, "FOLD_FOLLOW", 1.0)  # its folds as the playhead gave them
    # nothing taken back before the push, as then (decision 0046; tests/inference/test_take_back.py)
    monkeypatch.setattr(collision, "PUSH_OUT", dataclasses.replace(collision.PUSH_OUT, take_back=False))
    limited = animator.animate(_walk())
    monkeypatch.setattr(detail, "FOLD_MAX_STRAIN", np.inf)
    unslacked = dataclasses.replace(collision.PUSH_OUT, stretch_slack=0.0)

    def as_written(file: str, **run):
        """The clip animated again as ``file`` holds it: equal where 31b4ef9's limit moved nothing
        (offline, on the frames the clip's own windows blend alone: :func:`_blended_alike`)."""
        old = read_animation_h5(DATA / "out-31b4ef9" / file)
        kept = slice(None) if run.get("causal") else _blended_alike(animator, old.num_frames)
        monkeypatch.setattr(collision, "PUSH_OUT", dataclasses.replace(unslacked, max_strain=np.inf))
        unlimited = animator.animate(_walk(), **run).vertices[kept]
        left = (np.abs(unlimited - old.vertices[kept]) <= 1e-6).all((1, 2))
        monkeypatch.setattr(collision, "PUSH_OUT", unslacked)
        anim = animator.animate(_walk(), **run)
        gap = np.abs(anim.vertices[kept] - old.vertices[kept])
        assert left.mean() > 0.6 and gap[left].max() <= 1e-5
        assert gap.max() < 0.03  # the repair: undone as far as it tears, either way
        return anim, old

    anim, written = as_written("auto.h5")
    assert anim.settings["mode"] == written.attrs["mode"] == "detail"
    strain = [
        animator.edge_limits.lengths(v.astype(np.float64)) / animator.edge_limits.rest_length
        for v in (anim.vertices, limited.vertices)
    ]
    assert (
        strain[1].max() <= max(strain[0].max(), 1.0) + 0.1
        and np.abs(limited.vertices - anim.vertices).max() < 0.02
    )
    monkeypatch.setattr(blending, "DEPARTURE_ONLY", False)  # the whole latent inertialized, as then
    again, causal = as_written("residual-causal.h5", mode="residual", causal=True)
    assert np.array_equal(again.match, causal.match) and (again.match >= 0).all()


def test_a_version_2_out_h5_reads_with_the_version_3_names():
    residual = read_animation_h5(DATA / "out-31b4ef9" / "residual-causal.h5")
    assert residual.attrs["format_version"] == 3
    # version 2 marked every residual frame as retrieved; version 3 records its match only
    assert not residual.retrieved.any() and (residual.match >= 0).all()
    auto = read_animation_h5(DATA / "out-31b4ef9" / "auto.h5")
    assert auto.retrieved.dtype == np.uint8 and auto.match.shape == (auto.num_frames, 2)


def test_writing_into_a_version_2_bundle_upgrades_its_manifest(tmp_path):
    folder = shutil.copytree(DATA / "bundle-31b4ef9", tmp_path / "model")
    before = Animator.load(folder).animate(_walk(), mode="hybrid", push_out=False).vertices
    update_manifest(folder)
    on_disk = json.loads((folder / "bundle.json").read_text())
    assert on_disk["format_version"] == 5 and "gates" in on_disk and "detail_strength" in on_disk["auto"]
    assert on_disk["folds"]["encoding"] == "int8"  # the store as it was written
    assert "manifest_hash" in on_disk
    after = Animator.load(folder).animate(_walk(), mode="hybrid", push_out=False).vertices
    assert np.array_equal(before, after)


def test_every_driver_of_the_frame_path_gives_what_it_gave_before_the_stages_were_one_list(monkeypatch):
    """The fixture bundle's frames through each driver, as commit 22a6010 (before the frame path
    became one stage list) gave them: every fourth frame of a 2 s walk (a spin beside it in the
    crowd). Bit-identical on the machine that wrote them (an AVX2 EPYC); the tolerance is for
    other CPUs' kernels. The fold playhead never rests, as then (the crowd's spinning characters
    repeat a proposal; the rest is tested in tests/inference/test_detail.py)."""
    import dataclasses

    from hrr_garment.inference import collision, fold_track
    from hrr_garment.inference import stream as stream_module
    from hrr_garment.motion.poses import motion_to_poses

    restless = partial(fold_track.FoldTrack, rest=10**9)
    for module in (fold_track, stream_module):  # the offline track and the stream's
        monkeypatch.setattr(module, "FoldTrack", restless)
    # nothing taken back before the push, as then (decision 0046; tests/inference/test_take_back.py)
    monkeypatch.setattr(collision, "PUSH_OUT", dataclasses.replace(collision.PUSH_OUT, take_back=False))

    before = np.load(DATA / "frame-path-22a6010.npz")
    animator = Animator.load(DATA / "bundle-31b4ef9")
    walk, spin = _walk(), synthesize("spin", seconds=2, seed=5)
    frames = range(walk.num_frames)
    stream, crowd = animator.stream(), animator.crowd(device="native")
    torch_crowd = animator.crowd(mode="regression", device="cpu")
    rotations, roots = motion_to_poses(walk)
    now = {
        "v2__auto__causal0__col1": animator.animate(walk).vertices,
        "v2__hybrid__causal1__col1": animator.animate(walk, mode="hybrid", causal=True).vertices,
        "v2__residual__causal0__col0": animator.animate(walk, mode="residual", push_out=False).vertices,
        "v2__stream": np.stack([stream.push(walk.slice(t, t + 1)) for t in frames]),
        "v2__crowd": np.stack(
            [
                crowd.push_motions({k: m.slice(t, t + 1) for k, m in zip("abc", (walk, spin, spin))})
                for t in frames
            ]
        ),
        "v2__torch": np.stack([torch_crowd.push(rotations[t : t + 1], roots[t : t + 1]) for t in frames]),
    }
    assert set(now) == set(before.files)
    offline = _blended_alike(animator, walk.num_frames, settle=animator.window)  # the folds' 0.6 a frame
    for name, vertices in now.items():
        kept = np.arange(walk.num_frames)[offline if "causal0" in name else slice(None)]
        kept = kept[kept % 4 == 0]  # the file holds every fourth frame
        assert np.abs(vertices[kept] - before[name][kept // 4]).max() <= 1e-5, name


def test_an_out_h5_before_version_5_names_its_body_in_the_attribute_body(tmp_path):
    """Versions 1-4 named the body animated on in the attribute ``body``; version 5 writes ``body_name``
    (beside ``body_record`` and the ``body/`` group, the body itself), and older files read into it."""
    import h5py

    from hrr_garment.data.animation_versions import FORMAT_VERSION
    from hrr_garment.inference.animation import Animation

    motion = synthesize("walk", 0.2, seed=0)
    joints = motion.joint_positions.astype(np.float32)
    t = len(joints)
    anim = Animation(
        joints[:, :1] + np.zeros((1, 3, 3), np.float32),  # every vertex at the pelvis
        np.array([[0, 1, 2]]),
        30.0,
        np.zeros(t, np.uint8),
        np.zeros(t, np.float32),
        -np.ones((t, 2), np.int32),
        joints,
        "skirt",
        "hash",
        "walk",
        body_name="hero",
    )
    path = anim.save(tmp_path / "out.h5")
    with h5py.File(path, "a") as f:
        assert f.attrs["format_version"] == FORMAT_VERSION == 5 and f.attrs["body_name"] == "hero"
        assert "body" not in f.attrs
        f.attrs["format_version"] = 4  # as version 4 wrote it
        f.attrs["body"] = f.attrs.pop("body_name")
    old = read_animation_h5(path)
    assert old.attrs["body_name"] == "hero" and "body" not in old.attrs
    assert old.attrs["format_version"] == 4  # the arrays are version 4's: only the attribute is renamed
    assert np.array_equal(old.vertices, anim.vertices)
