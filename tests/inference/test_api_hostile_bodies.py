"""The Python API's doors with bodies (issue 88): a body record made in code is held to what
body.json's reader checks, so NaN, absurd capsules and upside-down, mirrored or zero skeletons are
a ValueError naming the problem rather than NaN or faraway vertices; a path where a clip goes loads;
what is not a clip or not numbers is a TypeError naming the argument."""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from hrr_garment import synthesize
from hrr_garment.body.body_file import BodyRecord
from hrr_garment.body.capsules import DEFAULT_BODY, BodyModel
from hrr_garment.inference.animator import Animator
from hrr_garment.motion.io import save_motion
from hrr_garment.motion.skeleton import Skeleton

BUNDLE = Path(__file__).resolve().parents[1] / "fixtures" / "bundle-31b4ef9"


@pytest.fixture(scope="module")
def animator() -> Animator:
    return Animator.load(BUNDLE)


def _record(offsets=None, capsule=None, pelvis_height=None) -> BodyRecord:
    skeleton = DEFAULT_BODY.skeleton if offsets is None else Skeleton(offsets=np.asarray(offsets, np.float32))
    capsules = DEFAULT_BODY.capsules
    if capsule is not None:
        capsules = (replace(capsules[0], **capsule), *capsules[1:])
    height = DEFAULT_BODY.pelvis_height if pelvis_height is None else pelvis_height
    return BodyRecord(
        skeleton, BodyModel(capsules, skeleton=skeleton, pelvis_height=height), height, stature=1.7
    )


OFFSETS = DEFAULT_BODY.skeleton.offsets
HOSTILE = {
    "a NaN pelvis height": (dict(pelvis_height=float("nan")), "pelvis_height must be .*, got nan"),
    "a NaN capsule radius": (dict(capsule={"radius": float("nan")}), "radius.*got nan"),
    "a capsule 1e30 m long": (dict(capsule={"b": (0.0, 1e30, 0.0)}), "capsule hips b"),
    "upside down": (dict(offsets=OFFSETS * np.array([1.0, -1.0, 1.0])), "upside down"),
    "mirrored": (dict(offsets=OFFSETS * np.array([-1.0, 1.0, 1.0])), "mirrored"),
    "a zero skeleton": (dict(offsets=np.zeros_like(OFFSETS)), "upside down or flat"),
    "offsets of the wrong shape": (dict(offsets=OFFSETS[:5]), "'offsets' must hold 22"),
}


@pytest.mark.parametrize("case", list(HOSTILE))
def test_a_hostile_body_record_is_refused_by_animate_stream_and_crowd(animator, case):
    fields, phrase = HOSTILE[case]
    try:
        record = _record(**fields)
    except (ValueError, IndexError):  # offsets of the wrong shape may be refused where they are made
        assert case == "offsets of the wrong shape"
        return
    walk = synthesize("walk", 0.5, seed=0)
    with pytest.raises(ValueError, match=phrase):
        animator.animate(walk, body=record)
    with pytest.raises(ValueError, match=phrase):
        animator.stream(body=record)
    with pytest.raises(ValueError, match=phrase):
        animator.crowd().set_body("hero", record)


def test_a_clip_path_loads_and_what_is_no_clip_is_a_type_error(animator, tmp_path):
    walk = synthesize("walk", 0.5, seed=0)
    save_motion(walk, tmp_path / "walk.npz")
    by_path = animator.animate(str(tmp_path / "walk.npz"), push_out=False)
    assert by_path.vertices.shape[0] == walk.num_frames and np.isfinite(by_path.vertices).all()
    with pytest.raises(TypeError, match="motion must be a Motion or a motion file's path, not int"):
        animator.animate(42)
    with pytest.raises(TypeError, match="pose must be a one-frame Motion, not str"):
        animator.stream().push("walk")
    with pytest.raises(TypeError, match="rotations must be numbers"):
        animator.crowd().push("walk", np.zeros((1, 3)))
