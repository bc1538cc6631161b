"""Flat-shaded orthographic rendering of meshes for the previews and videos: a mesh to draw
(:class:`PreviewMesh`), the camera and its named views, the z-buffered triangles and the ground
grid, drawn with Pillow (the ``preview`` extra)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def pillow_modules():
    """PIL's Image and ImageDraw, or an ImportError that says how to install Pillow."""
    try:
        from PIL import Image, ImageDraw
    except ImportError:
        raise ImportError("preview images need Pillow: pip install 'hrr_garment[preview]'") from None
    return Image, ImageDraw


@dataclass(frozen=True)
class PreviewMesh:
    """One mesh of a preview frame (world or view frame: Y up; the character faces +Z at azimuth 0)."""

    vertices: np.ndarray
    faces: np.ndarray
    colour: tuple[int, int, int]


# Camera azimuth (degrees about +Y, from +Z towards +X) per named view: "left" looks at the
# character's left side (+X), "three-quarter" from front-left.
VIEWS = {"front": 0.0, "three-quarter": 35.0, "left": 90.0, "side": 90.0, "back": 180.0, "right": 270.0}


@dataclass(frozen=True)
class OrthoCamera:
    """An orthographic camera: ``azimuth``/``elevation`` in degrees, looking at ``target`` (world)."""

    azimuth: float = 0.0
    elevation: float = 0.0
    target: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @classmethod
    def named(cls, view: str, elevation: float = 0.0, target=(0.0, 0.0, 0.0)) -> "OrthoCamera":
        if view not in VIEWS:
            raise ValueError(f"unknown view {view!r}; choose from {', '.join(VIEWS)}")
        return cls(VIEWS[view], elevation, tuple(target))

    def axes(self) -> np.ndarray:
        """Rows: screen right, screen up, towards the camera (an orthonormal, right-handed basis)."""
        th, ph = np.radians(self.azimuth), np.radians(self.elevation)
        return np.array(
            [
                [np.cos(th), 0.0, -np.sin(th)],
                [-np.sin(th) * np.sin(ph), np.cos(ph), -np.cos(th) * np.sin(ph)],
                [np.sin(th) * np.cos(ph), np.sin(ph), np.cos(th) * np.cos(ph)],
            ]
        )

    def project(self, points: np.ndarray) -> np.ndarray:
        """(..., 3) world -> (..., 3) camera coordinates (right, up, towards the camera)."""
        return (points - np.asarray(self.target)) @ self.axes().T


def draw_meshes(
    image,
    meshes: list[PreviewMesh],
    camera: OrthoCamera,
    centre: tuple[float, float],
    scale: float,
    depth: np.ndarray | None = None,
):
    """Flat-shaded, two-sided, z-buffered triangles drawn over the PIL ``image``; returns the new image.
    The light comes from the camera and above. ``depth``: the z-buffer (the image's height x width,
    larger is nearer; -inf where nothing is drawn), filled in place where given."""
    from .raster import rasterize

    Image, _ = pillow_modules()
    light = np.array([0.0, 0.5, 1.0]) / np.sqrt(1.25)
    pixels = np.array(image)
    if depth is None:
        depth = np.full(pixels.shape[:2], -np.inf)
    for mesh in meshes:
        tri = camera.project(mesh.vertices)[mesh.faces]
        normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)
        shade = 0.35 + 0.65 * np.abs(normal @ light)
        screen = np.stack([centre[0] + tri[..., 0] * scale, centre[1] - tri[..., 1] * scale, tri[..., 2]], -1)
        rasterize(
            pixels, depth, screen, colours=np.clip(np.outer(shade, mesh.colour), 0, 255).astype(np.uint8)
        )
    return Image.fromarray(pixels)


def draw_ground(
    draw,
    camera: OrthoCamera,
    centre: tuple[float, float],
    scale: float,
    half_width: float,
    spacing: float = 0.5,
    width: int = 1,
) -> None:
    """Grid lines on y = 0 around the camera target, so translation over the ground shows."""
    tx, _, tz = camera.target

    def grid(c: float) -> np.ndarray:
        return (
            np.arange(np.ceil((c - half_width) / spacing), np.floor((c + half_width) / spacing) + 1) * spacing
        )

    lines = [((x, 0.0, tz - half_width), (x, 0.0, tz + half_width)) for x in grid(tx)]
    lines += [((tx - half_width, 0.0, z), (tx + half_width, 0.0, z)) for z in grid(tz)]
    for a, b in lines:
        ends = camera.project(np.array([a, b]))
        draw.line(
            [(centre[0] + e[0] * scale, centre[1] - e[1] * scale) for e in ends],
            fill=(205, 205, 200),
            width=width,
        )
