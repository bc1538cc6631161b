"""Hostile motion files (issue 26's recipes): each one is refused with a one-line error naming the
file and the limit or value at fault, before any large allocation, and nothing is written."""

import io
import zipfile

import numpy as np
import pytest

from hrr_garment import save_amass, save_motion, synthesize
from hrr_garment.errors import MotionError
from hrr_garment.motion.io import load_motion
from tests.cli.test_bad_input import expect_failure, good_bvh  # noqa: F401  (the fixture)


def _edit_bvh(source, tmp_path, name, edit):
    lines = source.read_text().splitlines()
    edit(lines)
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n")
    return path


def _frame_time(value):
    def edit(lines):
        lines[next(i for i, line in enumerate(lines) if line.startswith("Frame Time"))] = (
            f"Frame Time: {value}"
        )

    return edit


def _first_row(value):
    def edit(lines):
        i = next(i for i, line in enumerate(lines) if line.startswith("Frame Time")) + 1
        row = lines[i].split()
        row[4] = value
        lines[i] = " ".join(row)

    return edit


def _first_channels(text):
    def edit(lines):
        i = next(i for i, line in enumerate(lines) if "CHANNELS 3" in line)
        lines[i] = lines[i].split("CHANNELS")[0] + text

    return edit


@pytest.mark.parametrize(
    "name, edit, phrase",
    [
        ("frame-time-huge.bvh", _frame_time("1e300"), "frame time"),
        ("frame-time-100.bvh", _frame_time("100"), "frame time"),
        ("frame-time-zero.bvh", _frame_time("0"), "frame time"),
        ("value-huge.bvh", _first_row("1e308"), "beyond"),
        (
            "axis-twice.bvh",
            _first_channels("CHANNELS 3 Zrotation Xrotation Xrotation"),
            "X, Y and Z once each",
        ),
        (
            "position-twice.bvh",
            lambda lines: lines.__setitem__(
                next(i for i, line in enumerate(lines) if "CHANNELS 6" in line),
                "CHANNELS 6 Xposition Xposition Zposition Zrotation Yrotation Xrotation",
            ),
            "X, Y and Z once each",
        ),
        (
            "offset-huge.bvh",
            lambda lines: lines.__setitem__(
                next(i for i, line in enumerate(lines) if "OFFSET" in line), "OFFSET 1e308 0 0"
            ),
            "within",
        ),
    ],
)
def test_hostile_bvh_values_are_refused(capsys, tmp_path, good_bvh, name, edit, phrase):  # noqa: F811
    expect_failure(capsys, tmp_path, _edit_bvh(good_bvh, tmp_path, name, edit), phrase)


def test_a_bvh_nested_thousands_deep_is_refused_without_recursion(capsys, tmp_path):
    depth = 5000
    text = [
        "HIERARCHY",
        "ROOT j0",
        "{",
        "OFFSET 0 0 0",
        "CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation",
    ]
    for i in range(1, depth):
        text += [f"JOINT j{i}", "{", "OFFSET 0 1 0", "CHANNELS 3 Zrotation Xrotation Yrotation"]
    text += ["}"] * depth + [
        "MOTION",
        "Frames: 1",
        "Frame Time: 0.033333",
        " ".join(["0"] * (6 + 3 * (depth - 1))),
    ]
    path = tmp_path / "deep.bvh"
    path.write_text("\n".join(text) + "\n")
    expect_failure(capsys, tmp_path, path, "at most 64 levels")


def test_frame_limits_are_explicit_and_raisable(capsys, tmp_path, good_bvh, monkeypatch):  # noqa: F811
    monkeypatch.setenv("HRR_MAX_FRAMES", "20")  # the 30-frame clip is over it
    expect_failure(capsys, tmp_path, good_bvh, "HRR_MAX_FRAMES")
    monkeypatch.setenv("HRR_MAX_FRAMES", "40")
    assert load_motion(good_bvh).num_frames == 30
    # a 120 fps clip resamples to 4 x fewer frames; a 1 fps one to 30 x more, checked before resampling
    monkeypatch.setenv("HRR_MAX_FRAMES", "100")
    slow = _edit_bvh(good_bvh, tmp_path, "slow.bvh", _frame_time("1"))
    with pytest.raises(MotionError, match="resample to 871 frames"):
        load_motion(slow)


def _npz(tmp_path, name, save, **overrides):
    """A one-second walk written by ``save`` (save_amass or save_motion), then rewritten with
    ``overrides`` replacing or adding arrays."""
    path = tmp_path / f"base-{save.__name__}.npz"
    save(synthesize("walk", seconds=1.0, seed=0), path)
    with np.load(path) as f:
        arrays = {k: f[k] for k in f.files}
    arrays.update(overrides)
    out = tmp_path / name
    np.savez(out, **arrays)
    return out


def _amass(tmp_path, name, **overrides):
    return _npz(tmp_path, name, save_amass, **overrides)


def _native(tmp_path, name, **overrides):
    return _npz(tmp_path, name, save_motion, **overrides)


@pytest.mark.parametrize(
    "name, overrides, phrase",
    [
        ("no-frames.npz", {"poses": np.zeros((0, 52, 3)), "trans": np.zeros((0, 3))}, "no frames"),
        ("rate-inf.npz", {"mocap_framerate": np.float64(np.inf)}, "frame rate"),
        ("rate-tiny.npz", {"mocap_framerate": np.float64(1e-6)}, "frame rate"),
        ("rate-text.npz", {"mocap_framerate": np.str_("sixty")}, "frame rate"),
        ("rate-array.npz", {"mocap_framerate": np.array([30.0, 60.0])}, "frame rate"),
        ("poses-complex.npz", {"poses": np.zeros((30, 156), np.complex128)}, "dtype complex128"),
        ("poses-bool.npz", {"poses": np.zeros((30, 156), bool)}, "real numbers"),
        ("poses-text.npz", {"poses": np.array(["a"] * 30)}, "real numbers"),
        ("poses-scaled.npz", {"poses": np.full((30, 156), 1000.0)}, "beyond"),
        ("trans-huge.npz", {"trans": np.full((30, 3), 1e300)}, "beyond"),
        ("poses-dates.npz", {"poses": np.zeros((30, 156), "datetime64[s]")}, "dtype"),
    ],
)
def test_hostile_amass_files_are_refused(capsys, tmp_path, name, overrides, phrase):
    expect_failure(capsys, tmp_path, _amass(tmp_path, name, **overrides), phrase)


@pytest.mark.parametrize(
    "name, change, phrase",
    [
        ("scaled.npz", lambda r: r * 1000, "beyond"),
        ("zeros.npz", lambda r: r * 0, "not a rotation"),
        ("reflected.npz", lambda r: r * np.array([-1.0, 1.0, 1.0])[:, None], "not a rotation"),
    ],
)
def test_native_rotations_must_be_rotations(capsys, tmp_path, name, change, phrase):
    rot = synthesize("walk", seconds=1.0, seed=0).local_rotations.astype(np.float32)
    expect_failure(capsys, tmp_path, _native(tmp_path, name, local_rotations=change(rot)), phrase)


@pytest.mark.parametrize(
    "name, overrides, phrase",
    [
        ("fps-zero.npz", {"fps": np.float64(0.0)}, "frame rate"),
        ("fps-nan.npz", {"fps": np.float64(np.nan)}, "frame rate"),
        ("version-text.npz", {"version": np.str_("one")}, "version"),
        ("height-negative.npz", {"source_height_m": np.float64(-1.7)}, "height"),
        ("source-number.npz", {"source": np.arange(4)}, "must be a string"),
        (
            "root-teleports.npz",
            {"root_translation": np.where(np.arange(30)[:, None] == 10, 50.0, 0.0) + np.array([0, 0.9, 0])},
            "m/s",
        ),
    ],
)
def test_hostile_native_files_are_refused(capsys, tmp_path, name, overrides, phrase):
    expect_failure(capsys, tmp_path, _native(tmp_path, name, **overrides), phrase)


def _npy_header(shape, dtype="<f8") -> bytes:
    out = io.BytesIO()
    np.lib.format.write_array_header_1_0(out, {"descr": dtype, "fortran_order": False, "shape": shape})
    return out.getvalue()  # magic string included


def test_huge_declared_shapes_and_compression_bombs_are_refused_before_allocation(
    capsys, tmp_path, monkeypatch
):
    claims = tmp_path / "claims.npz"  # a header declaring 26 GiB, with no data behind it
    with zipfile.ZipFile(claims, "w") as archive:
        archive.writestr("poses.npy", _npy_header((3_000_000, 156, 7)))
        archive.writestr("trans.npy", _npy_header((1, 3)))
    expect_failure(capsys, tmp_path, claims, "HRR_MAX_NPZ_BYTES")
    bomb = tmp_path / "bomb.npz"  # 64 MB of zeros that deflate to about 64 kB; limit lowered to 1 MB
    with zipfile.ZipFile(bomb, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("poses.npy", _npy_header((8_000_000,)) + bytes(64_000_000))
    assert bomb.stat().st_size < 200_000
    monkeypatch.setenv("HRR_MAX_NPZ_BYTES", str(1 << 20))
    expect_failure(capsys, tmp_path, bomb, "uncompressed")
    pickled = tmp_path / "objects.npz"
    np.savez(pickled, poses=np.array([{"a": 1}], dtype=object))
    expect_failure(capsys, tmp_path, pickled, "numbers and strings only")
