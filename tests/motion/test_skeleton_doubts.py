"""A skeleton that does not look like its joint names is named (issue 48, reproducer 13): names
swapped between two joints of a real CMU clip, in one chain, between chains and between sides."""

import re
import warnings

import pytest

from hrr_garment.errors import MotionError, SkeletonWarning
from hrr_garment.motion.io import load_motion


def swapped(text: str, a: str, b: str) -> str:
    return re.sub(rf"\b({a}|{b})\b", lambda m: b if m.group(1) == a else a, text)


@pytest.fixture
def cmu_text(mocap_dir) -> str:
    return (mocap_dir / "cmu" / "02_01.bvh").read_text()


def test_the_real_clip_raises_no_doubt(mocap_dir):
    with warnings.catch_warnings():
        warnings.simplefilter("error", SkeletonWarning)
        load_motion(mocap_dir / "cmu" / "02_01.bvh")


@pytest.mark.parametrize(
    "a, b, named",
    [
        (
            "LeftArm",
            "LeftForeArm",
            [
                "'LeftForeArm' (taken as l_elbow) is not below 'LeftArm' (taken as l_shoulder)",
                "the left elbow-wrist bone",
            ],
        ),
        (
            "LeftUpLeg",
            "LeftArm",
            [
                "'LeftLeg' (taken as l_knee) is not below 'LeftUpLeg' (taken as l_hip)",
                "the left hip-knee bone",
            ],
        ),
        ("LeftUpLeg", "RightUpLeg", ["'LeftUpLeg' (taken as l_hip) on the character's right"]),
        (
            "LeftFoot",
            "LeftToeBase",
            ["'LeftToeBase' (taken as l_foot) is not below 'LeftFoot' (taken as l_ankle)"],
        ),
    ],
)
def test_swapped_names_are_warned_about_with_the_joints_named(cmu_text, tmp_path, a, b, named):
    path = tmp_path / "swapped.bvh"
    path.write_text(swapped(cmu_text, a, b))
    with pytest.warns(SkeletonWarning) as caught:
        load_motion(path)
    message = str(caught[0].message)
    assert message.startswith(f"{path}: the skeleton does not look like its joint names")
    for phrase in named:
        assert phrase in message


def test_legs_measured_on_swapped_joints_say_why_the_unit_is_unknown(cmu_text, tmp_path):
    path = tmp_path / "legs.bvh"
    path.write_text(swapped(cmu_text, "LeftLeg", "RightLeg"))
    with pytest.raises(
        MotionError, match=r"cannot detect the length unit.*'LeftLeg' \(taken as l_knee\) is not below"
    ):
        load_motion(path)
