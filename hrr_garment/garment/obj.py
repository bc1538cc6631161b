"""Wavefront OBJ in and out, keeping vertex order (a simulated frame must match its template).

Reading: ``v`` lines, ``f`` lines (``i``, ``i/t``, ``i//n``, ``i/t/n``, negative indices), polygons
fan-triangulated, ``g``/``o`` names recorded per face. A garment's attached vertices are either the
vertices of the faces in a named group (``--attached waistband`` for ``g waistband``), or an
index file (one 0-based vertex index per line, or a .npy integer array).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..body.capsules import DEFAULT_BODY, BodyModel
from ..input_files import input_file
from ..io_utils import atomic_path
from .mesh import GarmentError, GarmentMesh, check_garment, repair_mesh

MAX_COORDINATE = 1e6  # file units (a millimetre OBJ of a 1,000 km garment): past it float32 loses the cloth
MIN_GARMENT_VERTICES = 16  # a garment to simulate: fewer is no cloth (a panel of 4 x 4 vertices)


def read_obj(path: str | Path) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """(vertices (V, 3) float64, triangles (F, 3) int64, {group name: face indices})."""
    path = Path(path)
    input_file(path, "a garment OBJ")
    verts: list[list[float]] = []
    faces: list[tuple[int, int, int]] = []
    groups: dict[str, list[int]] = {}
    current: list[str] = []
    with open(path, encoding="utf-8", errors="replace") as fh:
        for lineno, line in enumerate(fh, 1):
            parts = line.split()
            if not parts or parts[0].startswith("#"):
                continue
            tag = parts[0]
            try:
                if tag == "v":
                    verts.append([float(x) for x in parts[1:4]])
                    if len(verts[-1]) != 3:
                        raise ValueError("a vertex needs three coordinates")
                    if not all(map(math.isfinite, verts[-1])):  # never dropped with its faces later
                        raise ValueError("a vertex coordinate is not a finite number")
                    if max(map(abs, verts[-1])) > MAX_COORDINATE:  # float32 holds the garment
                        raise ValueError(f"a vertex coordinate beyond {MAX_COORDINATE:g} file units")
                elif tag == "f":
                    idx = [int(p.split("/")[0]) for p in parts[1:]]
                    idx = [i - 1 if i > 0 else len(verts) + i for i in idx]
                    if len(idx) < 3:
                        raise ValueError("a face needs at least three vertices")
                    for k in range(1, len(idx) - 1):  # fan triangulation of polygons
                        for name in current:
                            groups.setdefault(name, []).append(len(faces))
                        faces.append((idx[0], idx[k], idx[k + 1]))
                elif tag in ("g", "o"):
                    current = parts[1:] or ["default"]
            except ValueError as exc:
                raise GarmentError(path, f"line {lineno}: {exc}: {line.strip()[:60]!r}") from None
    if not verts or not faces:
        raise GarmentError(path, f"no mesh: {len(verts)} vertices, {len(faces)} faces")
    v, f = np.array(verts, np.float64), np.array(faces, np.int64)
    if f.min() < 0 or f.max() >= len(v):
        raise GarmentError(path, f"face indices out of range 1..{len(v)}")
    return v, f, {k: np.array(i, np.int64) for k, i in groups.items()}


def require_cloth(mesh: GarmentMesh, path: str | Path) -> GarmentMesh:
    """``mesh`` (read from ``path``) if it is enough cloth to simulate and learn, else a
    :class:`GarmentError`: the commands that simulate a user's OBJ ask it (a single triangle was
    once simulated and trained on)."""
    if mesh.num_vertices < MIN_GARMENT_VERTICES:
        raise GarmentError(
            path, f"{mesh.num_vertices} vertices: a garment to simulate has at least {MIN_GARMENT_VERTICES}"
        )
    return mesh


def read_obj_vertices(path: str | Path) -> np.ndarray:
    """Only the vertex positions (V, 3), in file order (for simulated frames)."""
    return read_obj(path)[0]


def format_rows(fmt: str, rows: np.ndarray) -> str:
    """``fmt % row`` for every row, newline-terminated: one string-format call for the whole array
    (about 10x faster than np.savetxt, which matters for OBJ sequences)."""
    rows = np.asarray(rows)
    return ((fmt + "\n") * len(rows)) % tuple(rows.ravel().tolist())


# one smoothing group for every face: importers (Blender's among them) otherwise shade cloth flat
SMOOTH_SHADING = "s 1\n"


def write_obj(
    path: str | Path, vertices: np.ndarray, faces: np.ndarray, groups: dict[str, np.ndarray] | None = None
) -> Path:
    """Write atomically, faces in their order. ``groups`` maps names to *vertex* sets: the faces
    whose vertices all lie in a set are put in a ``g`` group of that name, so reading the file with
    ``--attached NAME`` recovers the set (a set that spans no whole face needs an index file)."""
    path = Path(path)
    label = np.zeros(len(faces), np.int64)  # 0: the plain "garment" group
    names = ["garment"]
    for name, idx in (groups or {}).items():
        member = np.isin(faces, idx).all(1) & (label == 0)
        names.append(name)
        label[member] = len(names) - 1
    starts = np.flatnonzero(np.r_[True, label[1:] != label[:-1]])
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8") as fh:
        fh.write("# hrr_garment\n")
        fh.write(format_rows("v %.6f %.6f %.6f", vertices))
        fh.write(SMOOTH_SHADING)
        for k, start in enumerate(starts):
            stop = starts[k + 1] if k + 1 < len(starts) else len(faces)
            fh.write(f"g {names[label[start]]}\n")
            fh.write(format_rows("f %d %d %d", faces[start:stop] + 1))
    return path


@dataclass(frozen=True)
class Placement:
    """Where a garment file's mesh goes: as it is (the canonical rest pose), or with ``fit`` placed on
    the body from another convention (:func:`~.fit.fit_garment`; ``up`` and ``unit`` override what
    it detects, and go only with ``fit``). ``body``: the body it was modelled on (``--made-for``;
    default the mannequin), whose torso ``--attached auto`` looks for."""

    fit: bool = False
    up: str | None = None
    unit: str | None = None
    body: BodyModel = DEFAULT_BODY


def load_garment_obj(
    path: str | Path,
    name: str | None = None,
    *,
    attached_group: str | None = None,
    attached_file: str | Path | None = None,
    repair: bool = True,
    placement: Placement = Placement(),
    notes: list[str] | None = None,
) -> GarmentMesh:
    """A user garment from OBJ, in the canonical rest pose (Y up, metres), checked.

    ``repair`` merges duplicate vertices (1 um), drops degenerate faces and makes the winding
    consistent; it never changes the vertex count of a clean mesh, so imported frames still match.
    ``placement`` (:class:`Placement`): with ``fit`` the file is in another convention and is placed
    on the body. ``attached_group="auto"`` (and no such group in
    the file): the top band on the torso (:func:`~.fit.auto_attached`). What was done is appended
    to ``notes``.
    """
    from .fit import auto_attached, fit_garment

    path = Path(path)
    notes = [] if notes is None else notes
    v, f, face_groups = read_obj(path)
    fit, up, unit = placement.fit, placement.up, placement.unit
    if fit:
        placed = fit_garment(v, f, up=up, unit=unit, source=str(path))
        v = placed.apply(v)
        notes.append(f"fitted {path.name}: {placed.describe()}")
    elif up is not None or unit is not None:
        raise GarmentError(path, "--up and --unit go with --fit")
    if attached_file is not None:
        attached_file = Path(attached_file)
        input_file(attached_file, "a list of attached vertices")
        try:
            idx = (
                np.load(attached_file, allow_pickle=False)
                if attached_file.suffix == ".npy"
                else np.loadtxt(attached_file, dtype=np.int64, ndmin=1)
            )
        except (OSError, ValueError) as exc:
            raise GarmentError(attached_file, f"not a list of vertex indices ({exc})") from None
        idx = np.asarray(idx, np.int64).ravel()
        if len(idx) and (idx.min() < 0 or idx.max() >= len(v)):
            raise GarmentError(attached_file, f"vertex indices must lie in [0, {len(v)})")
        attached = idx
    elif attached_group == "auto" and "auto" not in face_groups:
        attached = auto_attached(v, placement.body, source=str(path))
        notes.append(f"attached (auto): {len(attached)} vertices of the top band that lie on the torso")
    elif attached_group is not None:
        if attached_group not in face_groups:
            raise GarmentError(
                path, f"no group {attached_group!r}; groups in the file: {sorted(face_groups) or 'none'}"
            )
        attached = np.unique(f[face_groups[attached_group]].ravel())
    else:
        raise GarmentError(
            path,
            "no attached vertices given: name an OBJ group (--attached GROUP), an index file "
            "(--attached-file), or let the top band on the torso be found (--attached auto)",
        )
    mesh = GarmentMesh(
        name or path.stem,
        v.astype(np.float32),
        f.astype(np.int32),
        groups={"attached": attached.astype(np.int32)},
        attached_groups=("attached",),
    )
    if repair:
        mesh = repair_mesh(mesh)
    try:
        check_garment(mesh)
    except GarmentError as exc:
        raise GarmentError(path, exc.problem) from None
    return mesh
