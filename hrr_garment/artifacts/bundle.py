"""Model bundle: one directory with everything inference needs for one garment (docs/codespace.md).

Files (all arrays as safetensors, nothing pickled)::

    bundle.json                  format version, garment, configs, gate and tau, window, database names,
                                 sha256 of every other file and a content hash over them
    autoencoder.safetensors      mesh autoencoder (FCMAE) weights
    motion_encoder.safetensors   garment_encoder.safetensors   decoder.safetensors
    quantizer.safetensors        the quantiser's class embeddings
    stats.safetensors            motion feature and garment latent mean/std
    database.safetensors         retrieval database: codes, source sequence/frame, and the windows'
                                 latents and standardised motion, each frame once (or, in older
                                 bundles, every window in full: :class:`.database.CodeDatabase` reads both)
    template.safetensors         template vertices, faces, attached vertex indices, vertex groups (group/NAME)
    folds.safetensors            every database frame's simulated folds, for the detail mode (:mod:`.folds`)
    direct.safetensors           the direct-regression baseline (hrr-train --stage direct), where trained
    sampler.safetensors          the generative decoder, mode sample (hrr-train --stage sampler)
    subspace.safetensors         the fast decoder for games (hrr_garment/models/subspace.py), where trained

``bundle.json`` is written last (:mod:`.bundle_writer`): a directory without it (or whose files do
not match its hashes) is not a bundle, so an interrupted write never looks like a model. It is read
and checked by :func:`~.bundle_loader.load_bundle`; this module is the loaded :class:`Bundle`: what
it holds and what it derives from bundle.json (the gate's thresholds, the calibrated modes, the
bodies).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from ..body.body_file import BodyRecord, body_from_dict
from ..body.capsules import DEFAULT_BODY, BodyModel
from ..body.mannequin import mannequin_record
from ..body.measures import BodyRange, body_vector
from ..errors import InputError
from ..garment.material import Material, material_from
from ..garment.material_range import MaterialRange
from ..garment.mesh import GarmentMesh
from ..models.codespace import CodeSpace
from ..models.direct import DirectRegressor
from ..models.fcmae import MeshAutoencoder
from ..models.sampler import ClothSampler
from ..models.subspace import SubspaceDecoder
from ..motion.features import FeatureStats
from .auto_calibration import AutoCalibration
from .database import CodeDatabase
from .folds import FoldStore
from .free_cloth import free_cloth_weights, rest_hang_m
from .gate_signals import GATE_SIGNALS
from .manifest import BundleError
from .manifest_section import thawed
from .typed_manifest import Manifest


@dataclass
class Bundle:
    """A loaded model bundle: the networks, statistics, database and template inference needs."""

    folder: Path
    manifest: Manifest  # bundle.json, typed (:mod:`.typed_manifest`)
    autoencoder: MeshAutoencoder
    codespace: CodeSpace
    motion_stats: FeatureStats
    latent_stats: FeatureStats
    database: CodeDatabase
    template: GarmentMesh
    direct: DirectRegressor | None = None  # the direct-regression baseline, when trained
    sampler: ClothSampler | None = None  # the generative decoder (mode sample), when trained
    folds: FoldStore | None = (
        None  # the database frames' folds, for the detail mode (where the bundle has them)
    )
    subspace: SubspaceDecoder | None = (
        None  # the run-time decoder sized for games (``--decoder fast``), when trained
    )

    @property
    def tau(self) -> float:
        """The calibrated threshold of the model's gate (:attr:`gate`)."""
        return float(self.manifest.tau)

    @property
    def gate(self) -> str:
        """The hybrid's calibrated gate signal."""
        return self.manifest.gate

    def gate_tau(self, signal: str) -> float:
        """The threshold calibrated for gate ``signal``: :attr:`tau` for the model's own gate, the
        training's calibration of each other signal otherwise."""
        if signal == self.gate:
            return self.tau
        if signal not in GATE_SIGNALS:
            raise BundleError(self.folder, f"has no gate {signal!r}; the gates are {', '.join(GATE_SIGNALS)}")
        calibrated = self.manifest.gates.get(signal)
        if calibrated is None or calibrated.tau is None:
            raise BundleError(
                self.folder,
                f"was not calibrated for the {signal!r} gate (trained before it, or "
                "hrr-train --stage codespace again); give its threshold with --tau",
            )
        return float(calibrated.tau)

    @property
    def has_residual(self) -> bool:
        """Whether the residual mode can run: a calibrated weight and the database's motion windows."""
        return self.manifest.residual is not None and self.database.motion is not None

    def require_residual(self) -> None:
        """A BundleError, naming the model and the fix, where the residual mode cannot run."""
        if not self.has_residual:
            raise BundleError(
                self.folder,
                "has no calibrated residual weight (trained before the residual mode): run "
                f"hrr-train --stage codespace -o {self.folder} on its dataset again (the "
                "trained weights are kept; only the weight is calibrated)",
            )

    def require_sampler(self) -> None:
        """A BundleError, naming the model and the fix, where the sample mode cannot run."""
        if self.sampler is None:
            raise BundleError(
                self.folder,
                f"has no generative decoder for the sample mode: train one with hrr-train --stage sampler "
                f"-o {self.folder} on its dataset",
            )

    def require_subspace(self, needed_by: str | None = None) -> None:
        """A BundleError, naming the model and the fix, where the bundle has no fast decoder (its
        distilled subspace): the fast decoder itself, or ``needed_by`` (the subspace push) runs on it."""
        if self.subspace is None:
            user = f", which {needed_by} runs on" if needed_by else ""
            raise BundleError(
                self.folder,
                f"has no fast decoder{user}: distil one with hrr-train --stage subspace "
                "(or run the full decoder and the mesh push)",
            )

    @property
    def residual_weight(self) -> float:
        """The residual mode's calibrated weight (:mod:`.residual`)."""
        self.require_residual()
        return float(self.manifest.residual.weight)

    @property
    def residual_nodes(self) -> np.ndarray | None:
        """(nodes,) the residual's free-cloth weight per latent node, as the auto calibration chose
        (bundle.json ``auto.residual_free_mm``), or None: the plain residual (:mod:`.residual`)."""
        ramp = self.auto.residual_free_mm
        return None if ramp is None else free_cloth_weights(self.node_hang_m, ramp)

    @property
    def fold_weights(self) -> np.ndarray | None:
        """(V, 1) the detail mode's folds' weight per vertex on free cloth, as the auto calibration
        chose (bundle.json ``auto.folds_free_mm``), or None: the folds everywhere
        (:mod:`hrr_garment.inference.detail`)."""
        ramp = self.auto.folds_free_mm
        return None if ramp is None else free_cloth_weights(self.vertex_hang_m, ramp)[:, None]

    @cached_property
    def vertex_hang_m(self) -> np.ndarray:
        """(V,) how far each vertex hangs from the body the garment was modelled on, at rest."""
        return rest_hang_m(self.template.vertices, self.made_for)

    @cached_property
    def node_hang_m(self) -> np.ndarray:
        """(nodes,) how far each latent node hangs from the body the garment was modelled on, at rest
        (its centre vertex's)."""
        return self.vertex_hang_m[np.asarray(self.autoencoder.hierarchy.node_vertices())]

    def require_folds(self) -> None:
        """A BundleError, naming the model and the fix, where the detail mode cannot run."""
        if self.folds is None:
            raise BundleError(
                self.folder,
                "has no simulated folds for the detail mode (trained before them): run "
                f"hrr-train --stage codespace -o {self.folder} on its dataset again (the "
                "trained weights are kept; only the folds are added)",
            )

    @property
    def detail_base(self) -> str:
        """The latents the detail mode puts its simulated folds on, as the auto calibration chose
        (:mod:`hrr_garment.eval.auto_mode`): "residual", the residual mode's, or "regression" (also
        before the calibration, and where the residual cannot run)."""
        base = self.auto.detail_base
        return (
            "residual"
            if base == "residual" and self.has_residual and self.residual_weight > 0
            else "regression"
        )

    @property
    def detail_strength(self) -> float:
        """The strength of the detail mode's simulated folds, as the auto calibration chose
        (:data:`~.folds.DETAIL_STRENGTH` before the calibration)."""
        return float(self.auto.detail_strength)

    @property
    def swing_gain(self) -> float:
        """The gain on the free cloth's swing the auto calibration chose (bundle.json
        ``auto.swing_gain``; 1, the swing as predicted, before it: :mod:`hrr_garment.inference.swing`)."""
        return float(1.0 if self.auto.swing_gain is None else self.auto.swing_gain)

    @property
    def auto(self) -> AutoCalibration:
        """bundle.json's ``auto``: what the auto calibration chose, or, before it ran, the hybrid
        with the default detail look."""
        return self.manifest.auto_or_uncalibrated

    @property
    def auto_mode(self) -> str:
        """The mode ``auto`` runs: the one calibrated at training (:mod:`hrr_garment.eval.auto_mode`);
        hybrid before the calibration, or where the mode it chose cannot run."""
        mode = self.auto.mode
        runnable = {"residual": self.has_residual, "detail": self.folds is not None}.get(mode, True)
        return mode if runnable else "hybrid"

    @property
    def body_range(self) -> BodyRange:
        """The range of the bodies the model was trained on (:mod:`hrr_garment.body.measures`):
        the mannequin alone for a model from before bodies."""
        bodies = self.manifest.bodies
        if bodies is None:
            return BodyRange.of([body_vector(mannequin_record())])
        try:
            return BodyRange.from_dict(thawed(bodies.range))
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise BundleError(self.folder, f"bundle.json's bodies are unreadable ({exc})") from None

    @property
    def material_range(self) -> MaterialRange | None:
        """The range of the cloths the model was trained in (:mod:`hrr_garment.garment.material_range`);
        None for a model from before cloths were recorded (it animates the cloth it learned)."""
        materials = self.manifest.materials
        if materials is None:
            return None
        try:
            return MaterialRange.from_dict(thawed(materials.range))
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise BundleError(self.folder, f"bundle.json's materials are unreadable ({exc})") from None

    @property
    def default_material(self) -> Material | None:
        """The cloth the model animates when given none (the project's default cloth where it
        was trained in it, else the middle of its range); None for a model from before cloths
        were recorded."""
        materials = self.manifest.materials
        if materials is None:
            return None
        try:
            return material_from(dict(thawed(materials.default)), "bundle.json's materials.default")
        except InputError as exc:
            raise BundleError(self.folder, f"bundle.json's default cloth is unreadable ({exc})") from None

    @property
    def default_body(self) -> BodyRecord:
        """The body the model animates when given none: the one body of a model trained on one,
        else the mannequin."""
        if self.manifest.default_body_is_mannequin:
            return mannequin_record()
        try:
            return body_from_dict(thawed(self.manifest.bodies.default), self.folder / "bundle.json")
        except InputError as exc:
            raise BundleError(self.folder, f"bundle.json's default body is unreadable ({exc})") from None

    @property
    def made_for(self) -> BodyModel:
        """The body the garment was modelled on (``hrr-simulate --made-for``), else the mannequin's."""
        bodies = self.manifest.bodies
        if bodies is None or bodies.made_for is None:
            return DEFAULT_BODY
        try:
            return body_from_dict(thawed(bodies.made_for), self.folder / "bundle.json").body
        except InputError as exc:
            raise BundleError(self.folder, f"bundle.json's made-for body is unreadable ({exc})") from None

    @property
    def garment(self) -> str:
        return self.manifest.garment

    @property
    def content_hash(self) -> str:
        return self.manifest.content_hash
