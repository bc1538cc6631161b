"""Reading a model bundle (:mod:`.bundle`) from its directory, and checking it on the way.

:func:`load_bundle` checks the version (older manifests are upgraded by
:func:`~.manifest.migrate_manifest`), every file's hash and every tensor's shape (:mod:`.bundle_parts`),
and the template's sampling hierarchy and the database's shapes against the networks' settings,
and says which and why when one is off: a :class:`~.manifest.BundleError` naming the bundle.
"""

from __future__ import annotations

from pathlib import Path

from ..errors import HRRError
from ..garment.material_range import MATERIAL_FEATURES
from ..garment.mesh import GarmentError, GarmentMesh, check_garment
from ..models.codespace import CodeSpace, CodeSpaceSettings
from ..models.direct import DirectRegressor, DirectSettings
from ..models.fcmae import AutoencoderSettings, MeshAutoencoder
from ..models.hierarchy import cached_hierarchy
from ..models.sampler import ClothSampler, SamplerSettings
from ..motion.features import FeatureStats
from ..settings import require_number
from .bundle import Bundle
from .bundle_parts import load_arrays, load_folds, load_state, load_subspace
from .database import CodeDatabase
from .manifest import NETWORKS, BundleError
from .manifest_section import thawed
from .typed_manifest import read_manifest

MAX_SCALE_M = 10.0  # the autoencoder's vertex scale: the spread of a garment's training frames (centimetres)


def load_bundle(folder: str | Path, cache_dir: Path | None = None) -> Bundle:
    """Load and check a bundle written by :func:`write_bundle`."""
    folder = Path(folder)
    try:
        return _load_bundle(folder, cache_dir)
    except HRRError:
        raise
    except (KeyError, TypeError, ValueError, AttributeError, IndexError) as exc:
        # the last line of defence: an entry of bundle.json of a type or shape no check above foresaw
        raise BundleError(folder, f"bundle.json has a bad entry ({type(exc).__name__}: {exc})") from None


def _load_bundle(folder: Path, cache_dir: Path | None) -> Bundle:
    manifest = read_manifest(folder)
    try:
        ae_cfg = AutoencoderSettings.from_dict(thawed(manifest.autoencoder.config))
        cs_cfg = CodeSpaceSettings.from_dict(thawed(manifest.codespace.config))
        features = manifest.codespace.features
        latent_shape = manifest.codespace.latent_shape
        scale = manifest.autoencoder.scale
        require_number("bundle.json autoencoder", "scale", scale, low=0, high=MAX_SCALE_M, above=True)
    except (KeyError, TypeError, ValueError) as exc:
        raise BundleError(folder, f"bundle.json has a bad or missing entry ({exc})") from None
    if features != cs_cfg.features:
        raise BundleError(
            folder,
            f"the model was trained on {features} motion features; its settings give {cs_cfg.features}",
        )
    if cs_cfg.material_features not in (0, len(MATERIAL_FEATURES)) or (
        cs_cfg.material_features and manifest.materials is None
    ):
        raise BundleError(
            folder,
            f"its code space reads {cs_cfg.material_features} cloth values; a model reads none or "
            f"{len(MATERIAL_FEATURES)}, and a model across cloths records their range (bundle.json "
            "materials)",
        )
    t = load_arrays(folder, "template.safetensors", ("vertices", "faces", "attached"))
    groups = {
        k.split("/", 1)[1]: v for k, v in t.items() if k.startswith("group/")
    }  # the template's vertex groups, if any
    template = GarmentMesh(
        manifest.garment,
        t["vertices"],
        t["faces"],
        groups={**groups, "attached": t["attached"]},
        attached_groups=("attached",),
    )
    try:
        check_garment(template)
    except GarmentError as exc:
        raise BundleError(folder, f"template.safetensors: {exc.problem}") from None
    hierarchy = cached_hierarchy(
        template.faces, template.num_vertices, cache_dir, **ae_cfg.hierarchy_options(), name=str(folder)
    )
    sizes = manifest.autoencoder.sizes
    if tuple(hierarchy.sizes) != sizes:
        raise BundleError(
            folder,
            f"the template's sampling hierarchy has levels {list(hierarchy.sizes)}, the model "
            f"{None if sizes is None else list(sizes)}",
        )
    autoencoder = MeshAutoencoder(hierarchy, ae_cfg, template.vertices, scale=float(scale))
    load_state(autoencoder, folder / "autoencoder.safetensors", folder)
    codespace = CodeSpace(cs_cfg, features, latent_shape)
    for name in NETWORKS:
        load_state(getattr(codespace, name), folder / f"{name}.safetensors", folder)
    s = load_arrays(folder, "stats.safetensors", ("motion_mean", "motion_std", "latent_mean", "latent_std"))
    d = load_arrays(folder, "database.safetensors", ("codes", "sequence", "start"))
    try:
        database = CodeDatabase.from_arrays(
            d, list(manifest.database.names), manifest.database.classes, cs_cfg.window
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise BundleError(folder, f"database: {exc}") from None
    if database.latents.shape[1:] != (cs_cfg.window, *latent_shape) or database.codes.shape[1:] != (
        cs_cfg.groups,
    ):
        raise BundleError(
            folder,
            f"database shapes {database.codes.shape} / {database.latents.shape} do not fit the configuration",
        )
    folds = (
        None if manifest.folds is None else load_folds(folder, manifest.folds, template, database=database)
    )
    direct = _trained_part(
        folder,
        manifest.direct,
        "direct",
        lambda config: DirectRegressor(DirectSettings.from_dict(config), features, latent_shape),
    )
    latent_size = latent_shape[0] * latent_shape[1]
    sampler = _trained_part(
        folder,
        manifest.sampler,
        "sampler",
        lambda config: ClothSampler(SamplerSettings.from_dict(config), features, latent_size),
    )
    if sampler is not None:
        try:
            sampler.check_calibration()
        except ValueError as exc:
            raise BundleError(folder, f"sampler.safetensors: {exc}") from None
    subspace = (
        None
        if manifest.subspace is None
        else load_subspace(folder, manifest.subspace, latent_shape, num_vertices=template.num_vertices)
    )
    return Bundle(
        folder,
        manifest,
        autoencoder.eval(),
        codespace=codespace.eval(),
        motion_stats=FeatureStats(s["motion_mean"], s["motion_std"]),
        latent_stats=FeatureStats(s["latent_mean"], s["latent_std"]),
        database=database,
        template=template,
        direct=direct,
        sampler=sampler,
        folds=folds,
        subspace=subspace,
    )


def _trained_part(folder: Path, entry, name: str, build):
    """An optional trained network of the bundle (``name``.safetensors), built by ``build`` from its
    entry's config and loaded, in eval mode; None where bundle.json has no ``name`` entry."""
    if entry is None:
        return None
    try:
        model = build(thawed(entry.config))
    except (KeyError, TypeError, ValueError) as exc:
        raise BundleError(folder, f"bundle.json has a bad {name!r} entry ({exc})") from None
    load_state(model, folder / f"{name}.safetensors", folder)
    return model.eval()
