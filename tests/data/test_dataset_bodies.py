"""Datasets on bodies other than the mannequin: each sequence names its body, the file keeps the
body and the garment on it, the motion read back is the body's own; symmetric bodies; splits
that hold out whole bodies; a build on a body through hrr-simulate --body."""

import json

import h5py
import numpy as np
import pytest

from hrr_garment.body.body_file import BodyRecord, write_body
from hrr_garment.body.capsules import DEFAULT_BODY
from hrr_garment.body.mannequin import MANNEQUIN
from hrr_garment.body.retarget import motion_on_body
from hrr_garment.body.symmetry import is_symmetric, symmetrized
from hrr_garment.cli.simulate import main as simulate_main
from hrr_garment.data.dataset import (
    DatasetError,
    GarmentDataset,
    SequenceRecord,
    write_dataset,
)
from hrr_garment.data.splits import combine_splits
from hrr_garment.garment.dressing import DressedBody
from hrr_garment.garment.templates import make_garment
from hrr_garment.garment.transfer import transfer_garment
from hrr_garment.motion.skeleton import REST_PELVIS_HEIGHT
from hrr_garment.motion.synth import synthesize
from hrr_garment.sim.parts import part_paths
from hrr_garment.sim.preset import CONFIG_DIR
from tests.garment.test_templates_on_bodies import _larger_body


def _dressed(garment, scale=1.1, fuller=1.2, name="tall"):
    body = _larger_body(scale, fuller)
    record = BodyRecord(body.skeleton, body, body.pelvis_height, stature=1.7 * scale)
    return DressedBody(name, record, transfer_garment(garment, made_for=DEFAULT_BODY, body=body)[0])


def test_a_dataset_keeps_each_sequences_body_and_the_garment_on_it(tmp_path):
    garment = make_garment("skirt", 200)
    tall = _dressed(garment)
    clip = synthesize("walk", 1.0, seed=0)
    on_body = motion_on_body(clip, tall.body)

    def carried(rest, motion):  # the rest shape carried along with the pelvis, as a garment goes
        return (rest[None] + (motion.root_translation - motion.root_translation[:1])[:, None]).astype(
            np.float32
        )

    frames = carried(tall.garment.vertices, on_body)
    records = [
        SequenceRecord("walk_tall", frames, on_body, {"kind": "walk"}, body_name="tall"),
        SequenceRecord("walk_mannequin", carried(garment.vertices, clip), clip),
    ]
    path = write_dataset(
        tmp_path / "d.h5", garment, records, {"train": ["walk_tall", "walk_mannequin"]}, bodies={"tall": tall}
    )
    ds = GarmentDataset(path)
    assert ds.body_name_of == {"walk_tall": "tall", "walk_mannequin": MANNEQUIN}
    rec = ds.sequence("walk_tall")
    assert rec.body_name == "tall"
    # the motion read back is the body's: its skeleton and its scaled root, the joints as simulated
    assert np.allclose(rec.motion.joint_positions, on_body.joint_positions, atol=1e-5)
    assert not np.allclose(rec.motion.joint_positions, clip.joint_positions, atol=1e-2)
    assert np.array_equal(ds.rest("walk_tall"), tall.garment.vertices)
    assert np.array_equal(ds.rest("walk_mannequin"), garment.vertices)
    kept = ds.bodies["tall"].body
    assert np.allclose(kept.radii, tall.body.radii, atol=1e-9) and kept.pelvis_height == pytest.approx(
        tall.body.pelvis_height
    )
    assert np.allclose(ds.sequence("walk_mannequin").motion.joint_positions, clip.joint_positions, atol=1e-5)


def test_a_sequence_on_a_body_the_file_does_not_hold_is_refused(tmp_path):
    garment = make_garment("skirt", 200)
    clip = synthesize("walk", 1.0, seed=0)
    frames = np.repeat(garment.vertices[None], clip.num_frames, 0)
    with pytest.raises(ValueError, match="bodies that were not given"):
        write_dataset(
            tmp_path / "d.h5",
            garment,
            [SequenceRecord("w", frames, clip, body_name="ghost")],
            {"train": ["w"]},
        )
    path = write_dataset(tmp_path / "d.h5", garment, [SequenceRecord("w", frames, clip)], {"train": ["w"]})
    with h5py.File(path, "a") as f:
        f["sequences/w"].attrs["body_name"] = "ghost"
    with pytest.raises(DatasetError, match="ghost"):
        GarmentDataset(path)


def test_a_version_2_dataset_names_each_sequences_body_in_its_old_attribute(tmp_path):
    """Version 2 named a sequence's body in the attribute ``body``, version 3 in ``body_name`` (``body``
    is the body record under /bodies): a version 2 file reads as before, into ``body_name``."""
    garment = make_garment("skirt", 200)
    tall = _dressed(garment)
    clip = motion_on_body(synthesize("walk", 1.0, seed=0), tall.body)
    root = clip.root_translation - clip.root_translation[:1]
    frames = (tall.garment.vertices[None] + root[:, None]).astype(np.float32)  # carried with the pelvis
    records = [SequenceRecord("w", frames, clip, body_name="tall")]
    path = write_dataset(tmp_path / "d.h5", garment, records, {"train": ["w"]}, bodies={"tall": tall})
    with h5py.File(path, "a") as f:
        assert f.attrs["format_version"] == 3 and f["sequences/w"].attrs["body_name"] == "tall"
        assert "body" not in f["sequences/w"].attrs
        f.attrs["format_version"] = 2  # as version 2 wrote it
        f["sequences/w"].attrs["body"] = f["sequences/w"].attrs.pop("body_name")
    ds = GarmentDataset(path)
    assert ds.body_name_of == {"w": "tall"} and ds.sequence("w").body_name == "tall"
    assert np.array_equal(ds.rest("w"), tall.garment.vertices)
    with h5py.File(path, "a") as f:
        f.attrs["format_version"] = 3  # a version 3 file's attribute ``body`` is not its body's name
    assert GarmentDataset(path).body_name_of == {"w": MANNEQUIN}


def test_nearly_symmetric_bodies_are_made_exactly_symmetric():
    body = _larger_body(1.05, 1.1)
    assert is_symmetric(DEFAULT_BODY)
    capsules = list(body.capsules)
    i = next(k for k, c in enumerate(capsules) if c.name == "l_upper_arm")
    capsules[i] = type(capsules[i])(**{**capsules[i].__dict__, "radius": capsules[i].radius + 0.01})
    lopsided = type(body)(tuple(capsules), skeleton=body.skeleton, pelvis_height=body.pelvis_height)
    assert not is_symmetric(lopsided)
    fixed = symmetrized(lopsided)
    assert is_symmetric(fixed)
    radius = {c.name: c.radius for c in fixed.capsules}
    assert radius["l_upper_arm"] == pytest.approx(radius["r_upper_arm"])
    capsules[i] = type(capsules[i])(**{**capsules[i].__dict__, "radius": capsules[i].radius + 0.2})
    very = type(body)(tuple(capsules), skeleton=body.skeleton, pelvis_height=body.pelvis_height)
    assert symmetrized(very) is very  # a body really lopsided stays as it is


def test_held_out_bodies_and_styles_combine():
    by_style = {"val": ["a1", "b1"], "test": ["c1", "c2"], "train": ["a2", "b2", "d1", "d2"]}
    by_body = {"val": ["d1"], "test": ["a2", "a1"], "train": ["b1", "b2", "c1", "c2", "d2"]}
    split = combine_splits(by_style, by_body)
    assert split == {"val": ["b1", "d1"], "test": ["a1", "a2", "c1", "c2"], "train": ["b2", "d2"]}


@pytest.mark.sim
def test_hrr_simulate_on_a_body_records_it_and_mirrors_on_it(tmp_path, capsys):
    pytest.importorskip("newton", reason="the sim extra is not installed")
    body = _larger_body(1.1, 1.15)
    body_file = write_body(
        tmp_path / "tall.json", BodyRecord(body.skeleton, body, body.pelvis_height, stature=1.87)
    )
    preset = tmp_path / "p.yaml"
    preset.write_text(f"extends: {CONFIG_DIR / 'presets' / 'tiny.yaml'}\nname: tiny-mirror\nmirror: true\n")
    out = tmp_path / "on-body.h5"
    assert (
        simulate_main(
            [
                "--garment",
                "skirt",
                "--preset",
                str(preset),
                "--motions",
                "walk",
                "--seconds",
                "1.0",
                "--body",
                str(body_file),
                "--jobs",
                "1",
                "--no-preview",
                "--quiet",
                "-o",
                str(out),
            ]
        )
        == 0
    )
    assert "body tall (1.87 m)" in capsys.readouterr().out
    ds = GarmentDataset(out)
    assert ds.body_name_of == {"walk_000": "tall", "walk_000_mirror": "tall"}
    rec = ds.sequence("walk_000")
    # ``mirror: true`` simulates the mirrored motion on the same body (not a reflection of the
    # source's frames)
    mirror = ds.sequence("walk_000_mirror")
    np.testing.assert_allclose(
        mirror.motion.joint_positions, rec.motion.mirrored().joint_positions, atol=1e-4
    )
    assert part_paths(out.with_suffix(".parts"), "walk_000_mirror")[
        0
    ].exists()  # simulated: a part of its own
    assert ds.info["summary"]["mirrored"] == 1
    assert rec.info["stats"]["penetration_max"] < 0.02 and rec.info["stats"]["strain_p99"] < 1.15
    # the clip played by this body: its pelvis higher by the legs' ratio, not the mannequin's
    clip = synthesize("walk", 1.0, seed=0)
    assert rec.motion.joint_positions[:, 0, 1] == pytest.approx(
        clip.joint_positions[:, 0, 1] * body.pelvis_height / REST_PELVIS_HEIGHT, abs=1e-4
    )
    recorded = json.loads(h5py.File(out, "r").attrs["info"])["bodies"]
    assert (recorded["from"], recorded["file"], recorded["placement"]["inside"]) == ("file", "tall.json", 0.0)
