"""The visible body's collider kept in the workspace: built once, read back equal (never rebuilt),
keyed by the body and the settings; a damaged file is built again."""

import numpy as np
import pytest

from hrr_garment.body import skin_collider_store
from hrr_garment.body.skin_collider import SkinColliderSettings
from hrr_garment.body.skin_collider_store import ARRAYS, collider_key, stored_skin_collider

from .limb import bent, near_surface, skinned_limb


def test_a_grid_is_built_once_and_read_back_equal(tmp_path, monkeypatch):
    body = skinned_limb()
    built = stored_skin_collider(body, folder=tmp_path)
    (path,) = tmp_path.glob("*.npz")
    assert path.stem == collider_key(body, SkinColliderSettings())

    def refuse(*args, **kwargs):
        raise AssertionError("built again")

    monkeypatch.setattr(skin_collider_store, "skin_collider", refuse)
    read = stored_skin_collider(body, folder=tmp_path)
    for name in ARRAYS:
        assert (
            np.array_equal(getattr(read, name), getattr(built, name))
            and getattr(read, name).dtype == getattr(built, name).dtype
        )
    rot, pos = bent(90.0)
    points, _ = near_surface(body, body.pose(rot[None], pos[None])[0])
    assert all(
        np.array_equal(a, b) for a, b in zip(read.query(points, rot, pos), built.query(points, rot, pos))
    )
    other = SkinColliderSettings(voxel_m=0.03)
    assert collider_key(body, other) != path.stem  # other settings: another grid
    with pytest.raises(AssertionError, match="built again"):
        stored_skin_collider(body, other, folder=tmp_path)


def test_a_damaged_file_is_built_again(tmp_path):
    body = skinned_limb()
    built = stored_skin_collider(body, folder=tmp_path)
    (path,) = tmp_path.glob("*.npz")
    path.write_bytes(path.read_bytes()[:200])  # cut short
    again = stored_skin_collider(body, folder=tmp_path)
    assert np.array_equal(again.face_list, built.face_list)
    assert (
        stored_skin_collider(body, folder=tmp_path).distance.shape == built.distance.shape
    )  # stored again, whole


def test_a_workspace_that_cannot_be_written_still_gives_the_grid(tmp_path):
    body = skinned_limb()
    blocked = tmp_path / "file"
    blocked.write_text("not a folder")  # the store's folder cannot be made under a file
    collider = stored_skin_collider(body, folder=blocked / "cache")
    assert np.array_equal(collider.face_list, stored_skin_collider(body, folder=tmp_path).face_list)
