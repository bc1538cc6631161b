"""USD export: a mesh whose points are time-sampled, one sample per frame.

The stage states its conventions explicitly (Y up, metersPerUnit 1, timeCodesPerSecond and
framesPerSecond = the animation's fps, time codes 0..T-1), so DCC tools need no guessing. The
file format follows the extension: .usd / .usdc binary crate, .usda text. Needs the ``export``
extra (usd-core).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..data.animation_file import AnimationFile
from ..errors import InputError, OutputError
from ..io_utils import atomic_path

USD_SUFFIXES = (".usd", ".usdc", ".usda")


def _pxr():
    try:
        from pxr import Sdf, Tf, Usd, UsdGeom, Vt
    except ImportError:
        raise ImportError("USD export needs usd-core: pip install 'hrr_garment[export]'") from None
    return Sdf, Tf, Usd, UsdGeom, Vt


def _define_mesh(
    stage, prim_path: str, faces: np.ndarray, frames, colour: tuple[float, float, float]
) -> None:
    """A triangle mesh at ``prim_path`` whose points and extent are sampled at time codes 0, 1, ..."""
    _, _, Usd, UsdGeom, Vt = _pxr()
    mesh = UsdGeom.Mesh.Define(stage, prim_path)
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(faces), 3, np.int32)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(np.ascontiguousarray(faces, np.int32).ravel()))
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    mesh.CreateDoubleSidedAttr(True)
    mesh.CreateDisplayColorAttr(Vt.Vec3fArray([colour]))
    points, extent = mesh.CreatePointsAttr(), mesh.CreateExtentAttr()
    for t, vertices in enumerate(frames):
        v = np.ascontiguousarray(vertices, np.float32)
        points.Set(Vt.Vec3fArray.FromNumpy(v), Usd.TimeCode(t))
        extent.Set(Vt.Vec3fArray.FromNumpy(np.stack([v.min(0), v.max(0)])), Usd.TimeCode(t))


def write_usd(anim: AnimationFile, path: str | Path, with_body: bool = False) -> Path:
    """Write an animation as USD (.usda or .usdc), with the body when asked; returns the path."""
    Sdf, Tf, Usd, UsdGeom, _ = _pxr()
    path = Path(path)
    if path.suffix.lower() not in USD_SUFFIXES:
        raise InputError(path, f"a USD file must end in {', '.join(USD_SUFFIXES)}")
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    stage.SetTimeCodesPerSecond(anim.fps)
    stage.SetFramesPerSecond(anim.fps)
    stage.SetStartTimeCode(0)
    stage.SetEndTimeCode(anim.num_frames - 1)
    root = UsdGeom.Xform.Define(stage, "/Animation")
    stage.SetDefaultPrim(root.GetPrim())
    # the rate again where Blender's importer reads it (userProperties become custom properties;
    # it takes the range from the stage but not the rate): the add-on sets the scene's from them
    for key, value, kind in (
        ("fps", float(anim.fps), Sdf.ValueTypeNames.Double),
        ("frames", int(anim.num_frames), Sdf.ValueTypeNames.Int),
    ):
        root.GetPrim().CreateAttribute(f"userProperties:{key}", kind, custom=True).Set(value)
    name = Tf.MakeValidIdentifier(str(anim.attrs.get("garment", "garment")))
    _define_mesh(stage, f"/Animation/{name}", anim.faces, anim.vertices, (0.27, 0.43, 0.78))
    if with_body:
        faces = anim.body_mesh(0)[1]
        _define_mesh(
            stage,
            "/Animation/body",
            faces,
            (anim.body_mesh(t)[0] for t in range(anim.num_frames)),
            (0.8, 0.76, 0.72),
        )
    with atomic_path(path) as tmp:
        try:
            written = stage.GetRootLayer().Export(
                str(tmp), args={"format": "usda" if path.suffix.lower() == ".usda" else "usdc"}
            )
        except Tf.ErrorException as exc:  # USD reports a full disk as a list of its own errors
            first = str(exc).strip().splitlines()[0] if str(exc).strip() else "USD could not write it"
            raise OutputError(
                path, f"cannot write the output: {first.split(': ', 1)[-1].strip(chr(39))}"
            ) from None
        if not written:
            raise OutputError(path, "cannot write the output: USD export failed")
    return path
