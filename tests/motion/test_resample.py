"""Resampling a faster capture to 30 fps: its motion kept, the noise above 15 Hz filtered out
rather than folded back into the motion (motion/resample.py)."""

import numpy as np
import pytest

from hrr_garment.motion.io import load_motion, native_frame_rate, save_motion
from hrr_garment.motion.motion import Motion
from hrr_garment.motion.resample import kernel_width, resample_linear, resample_rotations, resample_times
from hrr_garment.motion.rotations import axis_angle_to_matrix
from hrr_garment.motion.synth import synthesize
from tests.motion.test_gltf import write_canonical_bvh

NATIVE, OUT = 120.0, 30.0


def _signal(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A 1 Hz motion and, beside it, 37 Hz noise a tenth its size (37 Hz folds to 7 Hz at 30 fps)."""
    return 0.5 * np.sin(2 * np.pi * 1.0 * t), 0.05 * np.sin(2 * np.pi * 37.0 * t + 0.3)


@pytest.mark.parametrize("kind", ["translation", "rotation"])
def test_a_faster_capture_keeps_its_motion_and_loses_its_noise(kind):
    t_in = np.arange(int(4 * NATIVE)) / NATIVE
    motion, noise = _signal(t_in)
    frames = resample_times(len(t_in), NATIVE, OUT)
    truth, _ = _signal(frames / NATIVE)
    inner = slice(2, -2)  # the clip's ends average over fewer frames

    def read(width: float) -> np.ndarray:
        if kind == "translation":
            return resample_linear((motion + noise)[:, None], frames, width)[:, 0]
        axis = np.zeros((len(t_in), 3))
        axis[:, 0] = motion + noise  # an angle about x
        rot = resample_rotations(axis_angle_to_matrix(axis), frames, width)
        return np.arctan2(rot[:, 2, 1], rot[:, 1, 1])

    assert kernel_width(NATIVE, OUT) == 4.0 and kernel_width(OUT, OUT) == kernel_width(40.0, OUT) == 1.0
    decimated = np.abs(read(1.0) - truth)[inner].max()
    filtered = np.abs(read(kernel_width(NATIVE, OUT)) - truth)[inner].max()
    assert decimated > 0.03  # the noise, folded down to 7 Hz, is in the 30 fps motion
    # a fifth of it left; what remains is mostly the filter's slight rounding of the 1 Hz peak (0.4 %)
    assert filtered < 0.2 * decimated and filtered < 0.01


def test_a_30_fps_file_reads_as_before_and_a_faster_one_says_its_rate(tmp_path):
    """Same-rate reading is untouched (no filter), and the rate a file was captured at is read from
    it (what a dataset part's key needs)."""
    clip = synthesize("walk", 2.0, seed=0)
    save_motion(clip, tmp_path / "walk.npz")
    again = load_motion(tmp_path / "walk.npz")
    np.testing.assert_allclose(again.local_rotations, clip.local_rotations, atol=1e-6)
    fast = Motion(np.repeat(clip.local_rotations, 4, 0), np.repeat(clip.root_translation, 4, 0), 120.0)
    save_motion(fast, tmp_path / "fast.npz")
    assert (
        native_frame_rate(tmp_path / "fast.npz") == 120.0 and native_frame_rate(tmp_path / "walk.npz") == 30.0
    )
    bvh = tmp_path / "x.bvh"
    write_canonical_bvh(bvh, fast)
    assert native_frame_rate(bvh) == pytest.approx(120.0, rel=1e-3)
