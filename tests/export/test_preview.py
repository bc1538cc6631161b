"""The z-buffer rasterizer, the orthographic cameras and hrr-preview."""

from __future__ import annotations

import numpy as np
import pytest

from hrr_garment.data.animation_file import read_animation_h5
from hrr_garment.export.ortho_render import VIEWS, OrthoCamera, PreviewMesh, draw_meshes, pillow_modules
from hrr_garment.export.raster import rasterize
from tests.export.test_export import _animation_arrays, _write


def _blank(h=8, w=8):
    return np.zeros((h, w, 3), np.uint8), np.full((h, w), -np.inf)


@pytest.mark.parametrize("reverse", [False, True])
def test_rasterize_covers_pixel_centres_inside_any_winding(reverse):
    image, depth = _blank()
    tri = np.array([[[0, 0, 0], [4, 0, 0], [0, 4, 0]]], float)
    if reverse:
        tri = tri[:, ::-1]
    rasterize(image, depth, tri, np.array([[255, 0, 0]], np.uint8))
    covered = image[..., 0] == 255
    ys, xs = np.mgrid[:8, :8]
    assert np.array_equal(covered, (xs + 0.5) + (ys + 0.5) <= 4)  # 10 pixels: i + j <= 3
    assert covered.sum() == 10 and np.all(depth[covered] == 0) and np.all(np.isinf(depth[~covered]))


def test_rasterize_keeps_the_nearest_fragment_in_any_order():
    def square(x0, z):
        return np.array(
            [[[x0, 0, z], [x0 + 6, 0, z], [x0, 6, z]], [[x0 + 6, 0, z], [x0 + 6, 6, z], [x0, 6, z]]], float
        )

    near, far = square(0, 1.0), square(2, -1.0)
    colours = np.array([[10, 0, 0]] * 2 + [[0, 20, 0]] * 2, np.uint8)
    results = []
    for order in ([0, 1, 2, 3], [2, 3, 0, 1]):
        image, depth = _blank()
        tris = np.concatenate([near, far])[order]
        rasterize(image, depth, tris, colours[order])
        results.append(image.copy())
    assert np.array_equal(results[0], results[1])
    assert results[0][3, 4, 0] == 10 and results[0][3, 7, 1] == 20  # overlap: near wins; beyond it: far shows


def test_rasterize_sloped_depth_and_clipping():
    image, depth = _blank(4, 4)
    # a triangle much larger than the image, depth rising with x: clipped, depth interpolated
    tri = np.array([[[-10, -10, -10], [30, -10, 30], [-10, 30, -10]]], float)
    rasterize(image, depth, tri, np.array([[1, 2, 3]], np.uint8))
    assert np.all(image == [1, 2, 3])
    assert np.allclose(depth, np.broadcast_to(np.arange(4) + 0.5, (4, 4)), atol=1e-4)


@pytest.mark.parametrize("view", sorted(VIEWS))
@pytest.mark.parametrize("elevation", [0.0, 25.0])
def test_camera_axes_are_a_right_handed_orthonormal_basis(view, elevation):
    axes = OrthoCamera.named(view, elevation).axes()
    assert np.allclose(axes @ axes.T, np.eye(3), atol=1e-12) and np.isclose(np.linalg.det(axes), 1.0)
    assert axes[1, 1] > 0  # screen up points up
    if elevation == 0:
        assert axes[1] == pytest.approx([0, 1, 0])


def test_front_camera_sees_the_character_face_on():
    # the character faces +Z: its left (+X) appears on the right of a front view, nearer = larger depth
    cam = OrthoCamera.named("front")
    p = cam.project(np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]))
    assert p[0, 0] == pytest.approx(1.0) and p[1, 2] == pytest.approx(1.0)
    assert OrthoCamera.named("left").project(np.array([[1.0, 0, 0]]))[0, 2] == pytest.approx(1.0)


def test_draw_meshes_fills_the_depth_buffer_it_is_given():
    # two unit squares facing the front camera, at z = 0.5 and z = -0.5 (nearer = larger depth),
    # the far one shifted right: where they overlap the near one's depth, beyond it the far one's
    Image, _ = pillow_modules()
    quad = np.array([[0, 1, 2], [1, 3, 2]])
    square = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], float)
    meshes = [
        PreviewMesh(square + [0, 0, 0.5], quad, (10, 0, 0)),
        PreviewMesh(square + [0.5, 0, -0.5], quad, (0, 20, 0)),
    ]
    camera, blank = OrthoCamera.named("front", 0.0, target=(0.75, 0.5, 0.0)), Image.new("RGB", (40, 40))
    depth = np.full((40, 40), -np.inf)
    image = draw_meshes(blank, meshes, camera, (20, 20), 20.0, depth)
    assert np.array_equal(np.asarray(image), np.asarray(draw_meshes(blank, meshes, camera, (20, 20), 20.0)))
    row = depth[20]  # screen x = 20 + 20 (x - 0.75): the near square over 5..25, the far one 15..35
    assert np.allclose(row[6:24], 0.5) and np.allclose(row[26:34], -0.5)
    assert np.all(np.isinf(row[:4])) and np.all(np.isinf(row[36:]))


@pytest.fixture
def out_h5(tmp_path):
    return _write(tmp_path / "out.h5", _animation_arrays(24))


def test_hrr_preview_gif_png_and_mode_colours(out_h5, tmp_path):
    from PIL import Image

    from hrr_garment.cli.preview import main

    gif, png = tmp_path / "a.gif", tmp_path / "a.png"
    assert (
        main([str(out_h5), "-o", str(gif), "--size", "96", "--every", "2", "--views", "front", "back"]) == 0
    )
    with Image.open(gif) as im:
        assert im.n_frames == 12 and im.size == (192, 96)
    assert (
        main([str(out_h5), "-o", str(png), "--size", "96", "--frames", "3", "--color-mode", "--no-body"]) == 0
    )
    with Image.open(png) as im:
        sheet = np.asarray(im.convert("RGB")).astype(int)
    assert sheet.shape == (3 * 96, 2 * 96, 3)
    # frames 0, 12, 23 of the mode pattern (10 frames per mode): regression, retrieval, regression
    orange = sheet[..., 0] > sheet[..., 2] + 60
    per_row = orange.reshape(3, 96, -1).sum((1, 2))
    assert per_row[1] > 200 and per_row[0] == 0 and per_row[2] == 0


def test_hrr_preview_mp4(out_h5, tmp_path):
    from hrr_garment.cli.preview import main
    from hrr_garment.export.video import ffmpeg_executable

    try:
        ffmpeg_executable()
    except ImportError:
        pytest.skip("no ffmpeg (install the video extra)")
    import imageio_ffmpeg

    mp4 = tmp_path / "a.mp4"
    assert main([str(out_h5), "-o", str(mp4), "--size", "64", "--views", "front"]) == 0
    frames, seconds = imageio_ffmpeg.count_frames_and_secs(str(mp4))
    assert frames == 24 and seconds == pytest.approx(24 / 30, abs=0.05)


def test_hrr_preview_errors(out_h5, tmp_path, capsys):
    from hrr_garment.cli.preview import main

    arrays = _animation_arrays(6)
    del arrays["capsules"], arrays["radii"]
    v1 = _write(tmp_path / "v1.h5", arrays)
    assert main([str(v1), "-o", str(tmp_path / "x.gif"), "--size", "64"]) == 2
    assert "no body capsules" in capsys.readouterr().err
    assert main([str(v1), "-o", str(tmp_path / "y.gif"), "--size", "64", "--no-body"]) == 0
    assert main([str(out_h5), "-o", str(tmp_path / "x.avi")]) == 2
    assert "x.avi" in capsys.readouterr().err
    assert not list(tmp_path.glob("x*")) and not list(tmp_path.glob(".*"))
    assert read_animation_h5(v1).capsules is None


def test_the_render_pool_gives_the_frames_one_process_gives(out_h5):
    """Frames rendered by two worker processes, a few a task, come back complete and in order."""
    from hrr_garment.export.video import PreviewStyle, render_frames

    anim = read_animation_h5(out_h5)
    style = PreviewStyle(size=64, views=("front",))
    alone = [np.asarray(im) for im in render_frames(anim, style, progress=False, workers=1)]
    pooled = [np.asarray(im) for im in render_frames(anim, style, progress=False, workers=2)]
    assert len(alone) == len(pooled) == 24  # 24 >= 16 frames: the pool path
    assert all(np.array_equal(a, b) for a, b in zip(alone, pooled))
