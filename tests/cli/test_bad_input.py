"""Every kind of bad input exits non-zero with a message naming the file and the problem."""

import subprocess
import sys

import numpy as np
import pytest

from hrr_garment import save_amass, synthesize
from hrr_garment.cli.motion import main
from hrr_garment.motion.bvh_write import write_bvh
from hrr_garment.motion.skeleton import CANONICAL, JOINT_NAMES, PARENTS


@pytest.fixture
def good_bvh(tmp_path):
    motion = synthesize("walk", seconds=1.0, seed=0)
    path = tmp_path / "good.bvh"
    write_bvh(
        path,
        list(JOINT_NAMES),
        list(PARENTS),
        CANONICAL.offsets,
        motion.local_rotations.astype(np.float64),
        motion.root_translation,
        1 / 30,
    )
    return path


def run_features(capsys, path, tmp_path):
    out = tmp_path / "features.npy"
    code = main(["features", str(path), "-o", str(out)])
    err = capsys.readouterr().err
    return code, err, out


def expect_failure(capsys, tmp_path, path, *phrases):
    code, err, out = run_features(capsys, path, tmp_path)
    assert code != 0
    assert str(path) in err
    for phrase in phrases:
        assert phrase in err, err
    assert not out.exists()  # no partial output
    assert not list(tmp_path.glob(".features*"))  # no temporary left behind


def test_good_file_passes(capsys, tmp_path, good_bvh):
    code, _, out = run_features(capsys, good_bvh, tmp_path)
    assert code == 0 and np.load(out).shape == (30, 124)


def test_truncated_bvh(capsys, tmp_path, good_bvh):
    lines = good_bvh.read_text().splitlines()
    bad = tmp_path / "truncated.bvh"
    bad.write_text("\n".join(lines[: len(lines) - 10]) + "\n")
    expect_failure(capsys, tmp_path, bad, "truncated")
    header_only = tmp_path / "header.bvh"
    header_only.write_text("\n".join(lines[:20]) + "\n")
    expect_failure(capsys, tmp_path, header_only, "MOTION")


def test_channel_count_not_matching_rows(capsys, tmp_path, good_bvh):
    lines = good_bvh.read_text().splitlines()
    lines[-3] = lines[-3] + " 0.0 1.0"
    bad = tmp_path / "channels.bvh"
    bad.write_text("\n".join(lines) + "\n")
    expect_failure(capsys, tmp_path, bad, "expected 69 values")


def test_unknown_skeleton(capsys, tmp_path, good_bvh):
    text = good_bvh.read_text().replace("l_knee", "kneecap_thing").replace("r_elbow", "funny_bone")
    bad = tmp_path / "unknown.bvh"
    bad.write_text(text)
    expect_failure(capsys, tmp_path, bad, "unknown skeleton", "l_knee", "r_elbow", "--joint-map")


def test_nan_frames(capsys, tmp_path, good_bvh):
    lines = good_bvh.read_text().splitlines()
    vals = lines[-5].split()
    vals[7] = "nan"
    lines[-5] = " ".join(vals)
    bad = tmp_path / "nan.bvh"
    bad.write_text("\n".join(lines) + "\n")
    expect_failure(capsys, tmp_path, bad, "non-finite")
    motion = synthesize("walk", 1.0, seed=0)
    npz = tmp_path / "nan.npz"
    save_amass(motion, npz)
    data = dict(np.load(npz))
    data["poses"][3, 5] = np.nan
    np.savez(npz, **data)
    expect_failure(capsys, tmp_path, npz, "non-finite", "frame 3")


def test_npz_missing_keys_and_wrong_widths(capsys, tmp_path):
    motion = synthesize("walk", 1.0, seed=0)
    path = tmp_path / "amass.npz"
    save_amass(motion, path)
    data = dict(np.load(path))
    missing = tmp_path / "missing.npz"
    np.savez(missing, poses=data["poses"])
    expect_failure(capsys, tmp_path, missing, "missing keys", "trans")
    wide = tmp_path / "wide.npz"
    np.savez(wide, poses=np.zeros((30, 100)), trans=data["trans"], mocap_framerate=30.0)
    expect_failure(capsys, tmp_path, wide, "(T, 72|156|165)")
    mismatch = tmp_path / "mismatch.npz"
    np.savez(mismatch, poses=data["poses"], trans=data["trans"][:5], mocap_framerate=30.0)
    expect_failure(capsys, tmp_path, mismatch, "trans has shape")
    garbage = tmp_path / "garbage.npz"
    garbage.write_bytes(b"not a zip file")
    expect_failure(capsys, tmp_path, garbage, "not a readable npz")


def test_clip_shorter_than_one_window(capsys, tmp_path):
    path = tmp_path / "short.npz"
    save_amass(synthesize("walk", 0.2, seed=0), path)
    expect_failure(capsys, tmp_path, path, "shorter than one window")


def test_missing_file_and_unknown_extension(capsys, tmp_path):
    expect_failure(capsys, tmp_path, tmp_path / "nope.bvh", "not found")
    odd = tmp_path / "clip.c3d"
    odd.write_text("x")
    expect_failure(capsys, tmp_path, odd, "unsupported motion file type")


def test_console_script_exit_code(tmp_path):
    bad = tmp_path / "bad.bvh"
    bad.write_text("HIERARCHY\nROOT Hips\n{\n")
    proc = subprocess.run(
        [sys.executable, "-m", "hrr_garment.cli.motion", "info", str(bad)], capture_output=True, text=True
    )
    assert proc.returncode != 0 and str(bad) in proc.stderr and "Traceback" not in proc.stderr


def test_per_joint_poses_and_a_missing_frame_rate_load_with_fps(capsys, tmp_path):
    """AMASS-style poses given per joint (T, 52, 3) load like (T, 156); a file without a rate key is
    refused with a message that offers --fps, and loads with it."""
    motion = synthesize("walk", 1.0, seed=0)
    flat = tmp_path / "flat.npz"
    save_amass(motion, flat)
    data = dict(np.load(flat))
    per_joint = tmp_path / "per_joint.npz"
    np.savez(per_joint, poses=data["poses"].reshape(len(data["poses"]), 52, 3), trans=data["trans"])
    expect_failure(capsys, tmp_path, per_joint, "no frame rate", "--fps")
    out = tmp_path / "features.npy"
    assert main(["features", str(per_joint), "--fps", "30", "-o", str(out)]) == 0
    assert main(["features", str(flat), "-o", str(tmp_path / "flat.npy")]) == 0
    np.testing.assert_array_equal(np.load(out), np.load(tmp_path / "flat.npy"))
    # --fps re-times a file that has a rate: 60 given for a 30 fps clip halves its length.
    assert main(["info", str(flat), "--fps", "60", "--json"]) == 0
    assert '"frames": 15' in capsys.readouterr().out


@pytest.mark.parametrize("rate", ["0", "-30", "nan", "inf", "1e9"])
def test_bad_fps_values_are_refused(capsys, tmp_path, good_bvh, rate):
    code = main(["features", str(good_bvh), "--fps", rate, "-o", str(tmp_path / "f.npy")])
    err = capsys.readouterr().err
    assert code != 0 and "frame rate" in err and str(good_bvh) in err
    assert not (tmp_path / "f.npy").exists()


def test_bad_frame_rate_keys_are_refused(capsys, tmp_path):
    motion = synthesize("walk", 1.0, seed=0)
    path = tmp_path / "amass.npz"
    save_amass(motion, path)
    data = dict(np.load(path))
    for value in (0.0, -1.0, np.nan, np.array([30.0, 60.0]), np.str_("thirty")):
        bad = tmp_path / "bad_rate.npz"
        np.savez(bad, poses=data["poses"], trans=data["trans"], mocap_framerate=value)
        expect_failure(capsys, tmp_path, bad, "mocap_framerate", "frame rate")


def test_the_motion_and_body_commands_start_without_torch():
    """Reading a clip or a body needs no network: ``hrr-motion`` and ``hrr-body`` import in about a
    second, without the several seconds torch's import takes (a bundle is imported where it is read)."""
    script = (
        "import sys, hrr_garment.cli.motion, hrr_garment.cli.body\n"
        "print(sorted({'torch', 'scipy.signal'} & set(sys.modules)))"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"
