"""body.json: a body as a file, so that a character's body travels without its mesh library.

    write_body(path, body)        # a ParametricBody or a BodyRecord
    record = read_body(path)      # BodyRecord: skeleton, capsules, pelvis height, shape, fit report, mesh

It holds what the simulator, the push-out and retargeting need (the skeleton's offsets, the
capsules, the pelvis's height over the soles), where the body came from (the parametric shape,
when it has one, and how closely its capsules follow its surface) and, for a character fitted by
``hrr-body fit``, its own skinned mesh (:mod:`.mesh_record`: the body the viewer sees; an anny body's
is rebuilt from its shape). ``format_version`` moves when a field arrives or changes meaning: 2
brought ``mesh``. A file is written at the oldest version that holds it (1 without a mesh, so that
a body without one reads the same everywhere, its content hash included); older files are upgraded
in memory (:func:`_upgrade`) and a file of a newer version is refused. Written atomically; every
value is checked on reading, and a bad one is refused with the file and the field named.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..input_files import read_input_text
from ..io_utils import atomic_write_text, strict_json
from ..motion.skeleton import JOINT_NAMES, Skeleton
from .capsules import DEFAULT_BODY, BodyModel, Capsule
from .fit import FitReport
from .mesh_record import BodyMesh, mesh_from_dict, mesh_json, mesh_to_dict

FORMAT_VERSION = 2  # 2: a character's own skinned mesh ("mesh")
MAX_BONE_M = 1.5  # no bone of a human body is longer
MAX_RADIUS_M = 0.5
WITHOUT_MESH_VERSION = 1  # a body without a mesh is written as version 1 wrote it
MAX_FILE_BYTES = 64 << 20  # a body.json of the largest mesh kept (mesh_record.MAX_MESH_VERTICES) is ~25 MB


@dataclass(frozen=True)
class BodyRecord:
    """A body as body.json holds it."""

    skeleton: Skeleton
    body: BodyModel
    pelvis_height: float
    stature: float  # metres from the soles to the top of the head
    shape: dict | None = None  # the parametric shape's values, when the body has one
    report: FitReport | None = None
    mesh: BodyMesh | None = None  # its own skinned mesh (a fitted character's); None: rebuilt or none


def record_of(body) -> BodyRecord:
    """A :class:`BodyRecord` of a :class:`~.parametric.ParametricBody` (or a record itself)."""
    if isinstance(body, BodyRecord):
        return body
    fitted = body.fitted
    return BodyRecord(
        fitted.skeleton,
        fitted.body,
        fitted.pelvis_height,
        fitted.stature,
        shape=body.shape.to_dict(),
        report=fitted.report,
    )


def body_to_dict(body) -> dict:
    """body.json's content (a dict of JSON values) for a ParametricBody or a BodyRecord; datasets
    keep their bodies in the same form (:mod:`hrr_garment.data.dataset`)."""
    r = record_of(body)
    data = {
        "format_version": FORMAT_VERSION if r.mesh is not None else WITHOUT_MESH_VERSION,
        "joints": list(JOINT_NAMES),
        "offsets": np.asarray(r.skeleton.offsets, np.float64).round(6).tolist(),
        "pelvis_height": round(float(r.pelvis_height), 6),
        "stature": round(float(r.stature), 6),
        "capsules": [
            {"name": c.name, "joint": c.joint, "a": list(c.a), "b": list(c.b), "radius": c.radius}
            for c in r.body.capsules
        ],
        "shape": r.shape,
        "fit": r.report.to_dict() if r.report else None,
    }
    return data if r.mesh is None else {**data, "mesh": mesh_to_dict(r.mesh)}


def write_body(path: str | Path, body) -> Path:
    """Write body.json (atomically); a mesh one row a line (:func:`~.mesh_record.mesh_json`)."""
    path = Path(path)
    data = body_to_dict(body)
    mesh = data.pop("mesh", None)
    text = strict_json(data, indent=2)
    if mesh is not None:
        text = f'{text[:-2]},\n  "mesh": {mesh_json(mesh)}\n}}'
    atomic_write_text(path, text)
    return path


def _number(path: Path, what: str, value: object, low: float, high: float) -> float:
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float))
        or not math.isfinite(value)
        or not low <= value <= high
    ):
        raise InputError(path, f"{what} must be a number in [{low:g}, {high:g}], got {value!r}")
    return float(value)


def _vector(path: Path, what: str, value: object, limit: float) -> tuple[float, float, float]:
    if not isinstance(value, list) or len(value) != 3:
        raise InputError(path, f"{what} must be three numbers, got {value!r}")
    return tuple(_number(path, what, v, -limit, limit) for v in value)  # type: ignore[return-value]


def read_body(path: str | Path) -> BodyRecord:
    """Read and check body.json; problems raise :class:`InputError` naming the file and the field."""
    path = Path(path)
    text = read_input_text(path, limit=MAX_FILE_BYTES, what="a body file")
    try:
        data = json.loads(text)
    except RecursionError:
        raise InputError(path, "not a body file (its JSON is nested too deep)") from None
    except json.JSONDecodeError as exc:
        raise InputError(path, f"not a body file ({exc})") from None
    return body_from_dict(data, path)


def body_from_dict(data: object, path: str | Path) -> BodyRecord:
    """Check body.json's content (``path`` names where it came from in errors) and make its record."""
    path = Path(path)
    data = _upgrade(data, path)
    if data.get("joints") != list(JOINT_NAMES):
        raise InputError(path, f"'joints' must be the canonical joints {list(JOINT_NAMES)}")
    offsets = data.get("offsets")
    if not isinstance(offsets, list) or len(offsets) != len(JOINT_NAMES):
        raise InputError(path, f"'offsets' must hold {len(JOINT_NAMES)} joint offsets")
    skeleton = Skeleton(
        offsets=np.array(
            [_vector(path, f"offset of {n}", o, MAX_BONE_M) for n, o in zip(JOINT_NAMES, offsets)], np.float32
        )
    )
    _check_upright(path, skeleton)
    capsules = data.get("capsules")
    if not isinstance(capsules, list) or not capsules:
        raise InputError(path, "'capsules' must be a list of capsules")
    capsules = tuple(_capsule(path, c) for c in capsules)
    expected = [(c.name, c.joint) for c in DEFAULT_BODY.capsules]
    if [(c.name, c.joint) for c in capsules] != expected:  # what the push-out and the limbs index
        names = ", ".join(f"{name} on {joint}" for name, joint in expected)
        raise InputError(path, f"'capsules' must be the body's {len(expected)} capsules in order: {names}")
    pelvis_height = _number(path, "pelvis_height", data.get("pelvis_height"), 0.2, 2.0)
    body = BodyModel(capsules, skeleton=skeleton, pelvis_height=pelvis_height)
    shape = data.get("shape")
    if shape is not None and not (
        isinstance(shape, dict)
        and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in shape.values())
        and all(math.isfinite(v) for v in shape.values())
    ):
        raise InputError(path, f"'shape' must map phenotype names to finite numbers, got {shape!r}")
    fit = data.get("fit")
    if fit is not None and not isinstance(fit, dict):
        raise InputError(path, f"'fit' must be an object (the fit's report) or null, got {fit!r}")
    report = (
        FitReport(
            **{
                k: _number(path, f"fit {k}", fit.get(k), 0.0, 1e6)
                for k in ("mean_mm", "p95_mm", "outside_1cm", "inside_1cm")
            }
        )
        if fit
        else None
    )
    return BodyRecord(
        skeleton,
        body,
        pelvis_height,
        _number(path, "stature", data.get("stature"), 0.3, 3.0),
        shape=shape,
        report=report,
        mesh=None if data.get("mesh") is None else mesh_from_dict(data["mesh"], path),
    )


def _plain_number(value: object) -> object:
    """A numpy scalar as the Python number it holds (json's hook for what it cannot write)."""
    if getattr(value, "ndim", None) == 0 and callable(getattr(value, "item", None)):
        return value.item()
    raise TypeError(f"{type(value).__name__} is not a number")


def checked_record(record: BodyRecord, name: str = "body") -> BodyRecord:
    """A record made in code held to what body.json's reader checks (a NaN pelvis height, a capsule
    a kilometre long, offsets of the wrong shape, a skeleton upside down or mirrored): ``record``
    itself, or an :class:`InputError` naming ``name``. Its mesh is checked where it was made."""
    try:
        # through JSON as a reader sees it, NaN kept as NaN so that the error says "got nan"
        data = json.loads(json.dumps(body_to_dict(replace(record, mesh=None)), default=_plain_number))
    except (TypeError, ValueError, IndexError, AttributeError) as exc:
        raise InputError(name, f"not a body record ({exc})") from None
    body_from_dict(data, name)
    return record


def _upgrade(data: object, path: Path) -> dict:
    """body.json's content at :data:`FORMAT_VERSION`, one step per older version (version 1 had
    no ``mesh``); refused where it is not a body file or its version is unknown or newer."""
    if not isinstance(data, dict):
        raise InputError(path, "not a body file (not a JSON object)")
    version = data.get("format_version")
    if isinstance(version, bool) or not isinstance(version, int) or not 1 <= version <= FORMAT_VERSION:
        raise InputError(
            path, f"body format_version {version!r}; this hrr_garment reads 1 to {FORMAT_VERSION}"
        )
    if version == 1:
        if "mesh" in data:
            raise InputError(path, "a body file of format_version 1 holds no 'mesh' (version 2 brought it)")
        data = {**data, "mesh": None, "format_version": 2}
    return data


def _check_upright(path: Path, skeleton: Skeleton) -> None:
    """Refuse a skeleton no body has: upside down (the head below the pelvis, the feet above it) or
    mirrored (the left joints on the right: a body's left is +x, as the canonical skeleton's)."""
    joints = skeleton.rest_positions()
    at = {name: joints[i] for i, name in enumerate(JOINT_NAMES)}
    if not at["head"][1] > at["pelvis"][1] > max(at["l_ankle"][1], at["r_ankle"][1]):
        raise InputError(
            path, "its skeleton is upside down or flat: the head must stand above the pelvis, the feet below"
        )
    if not (at["l_hip"][0] > at["r_hip"][0] and at["l_shoulder"][0] > at["r_shoulder"][0]):
        raise InputError(
            path, "its skeleton is mirrored: the left hip and shoulder must lie on +x, the right on -x"
        )


def _capsule(path: Path, c: object) -> Capsule:
    if not isinstance(c, dict) or not isinstance(c.get("name"), str) or c.get("joint") not in JOINT_NAMES:
        raise InputError(path, f"a capsule needs a name and one of the canonical joints, got {c!r}")
    name = c["name"]
    return Capsule(
        name,
        c["joint"],
        a=_vector(path, f"capsule {name} a", c.get("a"), MAX_BONE_M),
        b=_vector(path, f"capsule {name} b", c.get("b"), MAX_BONE_M),
        radius=_number(path, f"capsule {name} radius", c.get("radius"), 1e-3, MAX_RADIUS_M),
    )
