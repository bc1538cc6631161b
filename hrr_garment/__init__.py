"""hrr_garment: loose-garment animation from body motion by hybrid retrieval-regression.

Public API (motion side)::

    from hrr_garment import load_motion, synthesize, motion_features
    motion = load_motion("walk.bvh")          # any BVH / glTF / AMASS npz / native npz -> canonical, 30 fps
    feats = motion_features(motion)            # (T, 124) float32

Garment side::

    from hrr_garment import make_garment, simulate_garment, GarmentDataset
    dress = make_garment("dress", vertices=1000)             # GarmentMesh fitted to the body
    result = simulate_garment(dress, motion)                  # needs the ``sim`` extra (newton)
    ds = GarmentDataset("hrr_work/datasets/dress-quick.h5")  # what hrr-simulate writes

Animation (after ``hrr-train --garment dress``)::

    from hrr_garment import Animator
    anim = Animator.load("dress").animate(load_motion("walk.bvh"))   # Animation, anim.save("out.h5")
"""

from ._version import __version__
from .data.dataset import GarmentDataset, SequenceRecord
from .errors import HRRError, InputError, MotionError, SkeletonMappingError
from .garment.fabrics import FABRICS
from .garment.material import Material, parse_material
from .garment.mesh import GarmentError, GarmentMesh
from .garment.templates import GARMENT_NAMES, make_garment
from .motion.features import FEATURE_DIM, FeatureStats, motion_features
from .motion.io import load_motion, save_amass, save_motion
from .motion.motion import Motion
from .motion.skeleton import CANONICAL, JOINT_NAMES
from .motion.synth import KINDS as MOTION_KINDS
from .motion.synth import synthesize
from .motion.windows import windows
from .sim.simulator import SimResult, SimSettings, SimulationExploded, simulate_garment

_LAZY = {
    "Animation": "inference.animation",
    "AnimationStream": "inference.character_stream",
    "CrowdStream": "inference.stream",
    "Animator": "inference.animator",
    "Bundle": "artifacts.bundle",
    "BundleError": "artifacts.bundle",
    "load_bundle": "artifacts.bundle_loader",
}


# the package's public names before the settings classes took one naming style (docs/architecture.md's
# glossary): still found, with a DeprecationWarning
RENAMED = {"SimConfig": "SimSettings"}


def __getattr__(name: str):
    """The inference API loads torch, FAISS and safetensors: imported on first use, so the motion
    and simulation tools start without them. An old public name (:data:`RENAMED`) gives its new one."""
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    if name in RENAMED:
        import warnings

        warnings.warn(f"hrr_garment.{name} is now {RENAMED[name]}", DeprecationWarning, stacklevel=2)
        return globals()[RENAMED[name]]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = [
    "__version__", "CANONICAL", "FEATURE_DIM", "FeatureStats", "HRRError", "InputError", "JOINT_NAMES",
    "MOTION_KINDS", "Motion", "MotionError", "SkeletonMappingError", "load_motion", "motion_features",
    "save_amass", "save_motion", "synthesize", "windows",
    "GARMENT_NAMES", "GarmentDataset", "GarmentError", "GarmentMesh", "SequenceRecord", "SimSettings",
    "SimResult", "SimulationExploded", "make_garment", "simulate_garment", "FABRICS", "Material",
    "parse_material",
    "Animation", "AnimationStream", "Animator", "CrowdStream", "Bundle", "BundleError", "load_bundle",
]  # fmt: skip
