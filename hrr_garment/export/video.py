"""Previews of an animation file: shaded frames from a few cameras, written as GIF, MP4 or a PNG
contact sheet. Needs the ``preview`` extra (Pillow); MP4 also needs an ffmpeg (the ``video`` extra
ships one, or one on PATH).

The cameras are orthographic and follow the pelvis over the ground (smoothed over one second, so
the body's own bob and sway stay visible), with a ground grid that shows the translation.
"""

from __future__ import annotations

import contextlib
import dataclasses
import multiprocessing
import os
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

import numpy as np
from tqdm import tqdm

from ..data.animation_file import AnimationFile
from ..errors import InputError, OutputError
from ..io_utils import atomic_path
from ..workers import DeferredSignals, die_with_parent, results_heeding
from .ortho_render import VIEWS, OrthoCamera, PreviewMesh, draw_ground, draw_meshes, pillow_modules

GARMENT = (70, 110, 200)
RETRIEVED = (225, 135, 45)  # garment colour on retrieved frames with --color-mode
BODY = (205, 195, 185)
PREVIEW_SUFFIXES = (".gif", ".mp4", ".png")


@dataclass(frozen=True)
class PreviewStyle:
    """How a preview is drawn: size, views, colours."""

    views: tuple[str, ...] = ("front", "left")
    size: int = 360  # pixels per view (square)
    metres: float = 2.3  # world height a view shows
    elevation: float = 12.0  # degrees the cameras look down
    with_body: bool = True
    color_mode: bool = False  # retrieval frames orange, regression blue
    supersample: int = 2  # rendered this many times larger, then downsampled (anti-aliasing)

    def __post_init__(self):
        unknown = [v for v in self.views if v not in VIEWS]
        if unknown or not self.views:
            raise InputError(
                "--views", f"unknown view(s) {', '.join(unknown) or '(none)'}; choose from {', '.join(VIEWS)}"
            )
        if self.size < 64:
            raise InputError("--size", f"at least 64 pixels, got {self.size}")


def _smooth_track(points: np.ndarray, fps: float) -> np.ndarray:
    """Centred moving average over about one second (edges use the shorter window)."""
    k = max(1, int(round(fps)))
    kernel = np.ones(k)
    pad = np.pad(points, ((k // 2, k - 1 - k // 2), (0, 0)), mode="edge")
    return np.stack([np.convolve(pad[:, i], kernel / k, mode="valid") for i in range(points.shape[1])], 1)


def render_scene(
    meshes: list[PreviewMesh], target: tuple[float, float, float], style: PreviewStyle, label: str = ""
):
    """One PIL image of ``meshes``: the style's views side by side, cameras aimed at ``target``
    (on the ground below the pelvis), with a ground grid and ``label`` in the corner."""
    Image, ImageDraw = pillow_modules()
    ss = max(1, style.supersample)
    cell = style.size * ss
    scale = cell / style.metres
    img = Image.new("RGB", (cell * len(style.views), cell), (250, 250, 247))
    for v, view in enumerate(style.views):
        camera = OrthoCamera.named(view, style.elevation, target)
        tile = Image.new("RGB", (cell, cell), (250, 250, 247))
        centre = (cell / 2, cell * 0.88)
        draw_ground(ImageDraw.Draw(tile), camera, centre, scale=scale, half_width=1.0, width=ss)
        img.paste(draw_meshes(tile, meshes, camera, centre=centre, scale=scale), (v * cell, 0))
    if ss > 1:
        img = img.resize((style.size * len(style.views), style.size), Image.LANCZOS)
    if label:
        ImageDraw.Draw(img).text((6, 4), label, fill=(40, 40, 40))
    return img


def render_frame(anim: AnimationFile, style: PreviewStyle, t: int, track: np.ndarray):
    """Frame ``t`` of ``anim``; ``track`` (T, 3) is where the cameras aim (see :func:`_smooth_track`)."""
    retrieved = bool(anim.retrieved[t])
    meshes = [
        PreviewMesh(
            anim.vertices[t].astype(np.float64),
            anim.faces,
            RETRIEVED if style.color_mode and retrieved else GARMENT,
        )
    ]
    if style.with_body:
        meshes.insert(0, PreviewMesh(*anim.body_mesh(t), BODY))
    label = f"frame {t}  {t / anim.fps:5.2f} s"
    cloth = anim.material
    if cloth is not None:  # which cloth, where the file records one (two side by side: which is which)
        label += f"  {cloth.name}"
    if style.color_mode:
        label += "  retrieval" if retrieved else "  regression"
    return render_scene(meshes, (track[t, 0], 0.0, track[t, 2]), style, label)


_WORKER: tuple = ()
FRAMES_A_TASK = 4


def _worker_init(parent_pid: int, anim: AnimationFile, style: PreviewStyle, track: np.ndarray) -> None:
    global _WORKER
    die_with_parent(parent_pid)
    _WORKER = (anim, style, track)


def _worker_render(frames: list[int]) -> list[tuple[tuple[int, int], bytes]]:
    """A few frames a task (one message each way for them), as (size, RGB bytes)."""
    images = [render_frame(_WORKER[0], _WORKER[1], int(t), _WORKER[2]) for t in frames]
    return [(image.size, image.tobytes()) for image in images]


def render_frames(
    anim: AnimationFile,
    style: PreviewStyle,
    frames: np.ndarray | None = None,
    progress: bool = True,
    workers: int | None = None,
) -> Iterator:
    """PIL images, in order, one per frame index in ``frames`` (default: all), views side by side.
    Frames are rendered by ``workers`` processes (default: one per CPU) when there are many."""
    Image, _ = pillow_modules()
    frames = np.arange(anim.num_frames) if frames is None else np.asarray(frames)
    track = _smooth_track(anim.joints[:, 0].astype(np.float64), anim.fps)
    workers = min(os.cpu_count() or 1, 8) if workers is None else workers
    bar = tqdm(total=len(frames), desc="render", unit="frame", disable=not progress)
    if workers <= 1 or len(frames) < 16:
        for t in frames:
            yield render_frame(anim, style, int(t), track)
            bar.update()
    else:
        # Ctrl-C and SIGTERM are held while the pool's internals run (raised there they can hang its
        # clean-up) and delivered between frames, or within a poll while a frame is late
        with (
            DeferredSignals() as signals,
            multiprocessing.get_context().Pool(
                workers, _worker_init, (os.getpid(), anim, style, track)
            ) as pool,
        ):
            # tasks of FRAMES_A_TASK frames, each its own imap item (an imap chunksize over 1 gives a
            # plain generator, which cannot wait with a timeout)
            tasks = [frames[i : i + FRAMES_A_TASK].tolist() for i in range(0, len(frames), FRAMES_A_TASK)]
            for rendered in results_heeding(pool.imap(_worker_render, tasks), signals):
                for size, data in rendered:
                    yield Image.frombytes("RGB", size, data)
                    bar.update()
    bar.close()


def ffmpeg_executable() -> str:
    """The ffmpeg the ``video`` extra installs, else one on PATH."""
    try:
        import imageio_ffmpeg

        return imageio_ffmpeg.get_ffmpeg_exe()
    except (ImportError, RuntimeError):
        pass
    found = shutil.which("ffmpeg")
    if found is None:
        raise ImportError(
            "MP4 previews need ffmpeg: pip install 'hrr_garment[video]' (or put ffmpeg on PATH)"
        )
    return found


def side_by_side(streams: list[Iterator]) -> Iterator:
    """One image per frame: each stream's image of that frame, left to right."""
    Image, _ = pillow_modules()
    for images in zip(*streams):
        row = Image.new("RGB", (sum(i.width for i in images), images[0].height))
        for k, image in enumerate(images):
            row.paste(image, (k * images[0].width, 0))
        yield row


def write_preview(
    anim: AnimationFile,
    path: str | Path,
    style: PreviewStyle = PreviewStyle(),
    every: int = 1,
    sheet_frames: int = 6,
    progress: bool = True,
    beside: tuple[AnimationFile, ...] = (),
) -> Path:
    """GIF or MP4 of every ``every``-th frame, or (.png) a contact sheet of ``sheet_frames`` evenly
    spaced frames one under the other (just the middle frame when 1). Written atomically.
    ``beside``: other animations of the same clip (the same garment in another cloth, say), each
    frame drawn to the right of ``anim``'s, over the frames they all have."""
    path = Path(path)
    if beside:
        frames = min(a.num_frames for a in (anim, *beside))
        anim, *beside = [_first_frames(a, frames) for a in (anim, *beside)]

    def render(chosen: np.ndarray) -> Iterator:
        streams = [
            render_frames(a, style, chosen, progress and k == 0) for k, a in enumerate((anim, *beside))
        ]
        return side_by_side(streams) if beside else streams[0]

    suffix = path.suffix.lower()
    if suffix not in PREVIEW_SUFFIXES:
        raise InputError(path, f"previews are {', '.join(PREVIEW_SUFFIXES)}, not {suffix or 'no extension'}")
    if every < 1:
        raise InputError("--every", f"must be >= 1, got {every}")
    if suffix == ".png":
        n = min(sheet_frames, anim.num_frames)
        chosen = (
            np.unique(np.linspace(0, anim.num_frames - 1, n).round().astype(int))
            if n > 1
            else np.array([anim.num_frames // 2])
        )  # one frame: the middle one
        images = list(render(chosen))
        Image, _ = pillow_modules()
        sheet = Image.new("RGB", (images[0].width, sum(i.height for i in images)))
        for k, im in enumerate(images):
            sheet.paste(im, (0, k * images[0].height))
        with atomic_path(path) as tmp:
            sheet.save(tmp, format="PNG")
        return path
    frames = np.arange(0, anim.num_frames, every)
    fps = anim.fps / every
    images = render(frames)
    with atomic_path(path) as tmp:
        if suffix == ".gif":
            first = next(images)
            # GIF delays are whole centiseconds; 30 fps plays at 33.3 fps-ish (3 cs) rather than drifting.
            first.save(
                tmp,
                format="GIF",
                save_all=True,
                append_images=list(images),
                loop=0,
                duration=max(20, int(round(100 / fps)) * 10),
                optimize=False,
            )
        else:
            width = style.size * len(style.views) * (1 + len(beside))
            _encode_mp4(images, tmp, fps, width, style.size, target=path)
    return path


def _first_frames(anim: AnimationFile, frames: int) -> AnimationFile:
    """``anim`` cut to its first ``frames`` frames (every per-frame array)."""
    if anim.num_frames == frames:
        return anim
    per_frame = (
        "vertices",
        "joints",
        "retrieved",
        "entropy",
        "match",
        "capsules",
        "rotations",
        "root_translation",
    )
    cut = {k: getattr(anim, k)[:frames] for k in per_frame if getattr(anim, k) is not None}
    return dataclasses.replace(anim, **cut)


def _encode_mp4(images: Iterator, path: Path, fps: float, width: int, height: int, target: Path) -> None:
    """H.264 (yuv420p, even dimensions) through an ffmpeg subprocess fed raw RGB frames, into
    ``path``; a failure (a full disk, say) is an :class:`OutputError` naming ``target``."""
    w, h = width + width % 2, height + height % 2
    cmd = [
        ffmpeg_executable(),
        "-y",
        "-loglevel",
        "error",
        "-f",
        "rawvideo",
        "-pix_fmt",
        "rgb24",
        "-s",
        f"{w}x{h}",
        "-r",
        f"{fps:g}",
        "-i",
        "-",
        "-an",
        "-c:v",
        "libx264",
        "-pix_fmt",
        "yuv420p",
        "-crf",
        "20",
        "-movflags",
        "+faststart",
        "-f",
        "mp4",
        str(path),
    ]
    proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        for im in images:
            frame = np.full((h, w, 3), 250, np.uint8)
            frame[:height, :width] = np.asarray(im)
            try:
                proc.stdin.write(frame.tobytes())
            except BrokenPipeError:  # ffmpeg stopped: its exit status and message say why
                break
    finally:
        with contextlib.suppress(BrokenPipeError):
            proc.stdin.close()
        err = proc.stderr.read().decode(errors="replace")
        if proc.wait() != 0:
            last = err.strip().splitlines()[-1] if err.strip() else f"exit status {proc.returncode}"
            raise OutputError(target, f"ffmpeg failed: {last[-300:]}")
