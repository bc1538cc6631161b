"""The Python API for animating a garment: :class:`Animator` and :class:`Animation` (streams: :mod:`.stream`).

from hrr_garment import Animator, load_motion
animator = Animator.load("dress")                 # hrr_work/models/dress-full, else dress-quick
anim = animator.animate(load_motion("walk.bvh"))  # offline, hybrid, collision push-out
anim.save("out.h5")

stream = animator.stream()                        # causal, one frame in, one frame out
for t in range(motion.num_frames):
    vertices = stream.push(motion.slice(t, t + 1))
crowd = animator.crowd()                          # many characters, one call a frame
vertices = crowd.push(rotations, roots, keys)     # (N, 22, 4) quaternions, (N, 3) -> (N, V, 3)
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import torch

from ..artifacts.bundle import Bundle, BundleError
from ..artifacts.bundle_loader import load_bundle
from ..body.body_file import BodyRecord
from ..garment.smoothing import mean_operator
from ..models.native_codes import native_window_codes
from ..motion.motion import Motion
from ..native import PRECISIONS
from ..paths import workspace
from . import collision
from .animation import Animation
from .character_body import CharacterBody, character_body
from .character_stream import AnimationStream
from .clip_path import animate_clip, clip_features
from .collision import PushOutSettings
from .decoding import flush_denormals
from .edge_limits import EdgeLimits
from .frame_path import FramePath, Observer
from .modes import CODE_MODES, Mode
from .run_material import material_columns, run_material
from .run_settings import ResolvedRun, RunSettings, run_settings
from .stream import CrowdStream
from .subspace_push import SubspacePush


def find_model(name_or_dir: str | Path) -> Path:
    """A model directory: the path itself, or hrr_work/models/NAME-full, else NAME-quick."""
    path = Path(name_or_dir)
    if (path / "bundle.json").is_file() or path.is_dir():
        return path
    tried = [workspace() / "models" / f"{name_or_dir}-{preset}" for preset in ("full", "quick")]
    for candidate in tried:
        if (candidate / "bundle.json").is_file():
            return candidate
    raise BundleError(
        name_or_dir,
        "no trained model: looked for "
        + ", ".join(str(t) for t in tried)
        + f" (train one with: hrr-train --garment {name_or_dir})",
    )


class Animator:
    """A loaded model bundle that animates its garment from body motion. ``settings`` and keyword
    ``changes`` (:class:`~.run_settings.RunSettings`' fields: ``Animator.load("dress",
    precision="bfloat16")``) are the run request every call without a settings object of its own
    starts from."""

    def __init__(self, bundle: Bundle, blend: int = 6, settings: RunSettings | None = None, **changes):
        self.bundle = bundle
        self.blend = blend  # inertialization frames in causal mode
        self.settings = run_settings(settings, changes)
        self._decoders: dict[str, object] = {}  # the full mesh decoder per precision (mesh_decoder)
        # the full mesh decoder in the settings' precision, built now: a precision the CPU lacks is
        # refused at load
        self.decoder = self.mesh_decoder(self.settings.precision or PRECISIONS[0])
        self.smoothing = mean_operator(
            bundle.template.faces, bundle.template.num_vertices
        )  # for the push-out
        self.edge_limits = EdgeLimits.of(
            bundle.template.faces, bundle.template.vertices, mean=self.smoothing
        )  # the push-out's
        self._causal_steps: dict[bool, object] = {}
        self._default_body: CharacterBody | None = None
        self._subspace_push: SubspacePush | None = None

    def mesh_decoder(self, precision: str):
        """The full mesh decoder (:class:`~hrr_garment.models.inference_decoder.InferenceDecoder`) in
        ``precision``'s arithmetic for batches of frames: "float32" or "bfloat16" (AMX on recent
        Intel Xeons: about 3x faster for crowds and offline animation); made once per precision."""
        if precision not in self._decoders:
            self._decoders[precision] = self.bundle.autoencoder.inference_decoder(precision=precision)
        return self._decoders[precision]

    @property
    def subspace_push(self) -> SubspacePush | None:
        """The push in the bundle's fast-decoder subspace (:mod:`.subspace_push`), made once; None without a
        fast decoder."""
        if self._subspace_push is None and self.bundle.subspace is not None:
            template = self.bundle.template
            self._subspace_push = SubspacePush.of(
                self.bundle.subspace.basis.numpy(), template.vertices, template.edges()
            )
        return self._subspace_push

    def push_settings(self, run: ResolvedRun) -> PushOutSettings | None:
        """The push-out's settings for ``run``: None (the product's, which push_out reads) or, where
        ``run.push`` asks for it, the product's with :attr:`subspace_push`."""
        if run.push != "subspace":
            return None
        return dataclasses.replace(collision.PUSH_OUT, subspace=self.subspace_push)

    def decoder_for(self, run: ResolvedRun):
        """The mesh decoder ``run`` asks for: the full one in its precision (:meth:`mesh_decoder`) or
        the bundle's fast subspace decoder (:mod:`hrr_garment.models.subspace`); both take (B, N, C)
        latents to (B, V, 3)."""
        return self.bundle.subspace if run.decoder == "fast" else self.mesh_decoder(run.precision)

    def causal_step(self, regression: bool):
        """The window step (:class:`~hrr_garment.models.codes.WindowCodes`' function) that causal inference
        runs, offline and streaming alike, so both compute the same bits: the native kernel
        (:mod:`hrr_garment.models.native_codes`), or None where it is unavailable (each path then
        uses its PyTorch form)."""
        if regression not in self._causal_steps:
            self._causal_steps[regression] = native_window_codes(
                self.bundle.codespace, regression, last_frame=True
            )
        return self._causal_steps[regression]

    @classmethod
    def load(cls, model: str | Path, settings: RunSettings | None = None, **changes) -> "Animator":
        """The model ``model`` (:func:`find_model`), with the run request its calls start from
        (``settings`` with keyword ``changes``, as the constructor takes them)."""
        return cls(load_bundle(find_model(model), workspace() / "cache"), settings=settings, **changes)

    @property
    def has_direct(self) -> bool:
        """Whether the bundle has the direct-regression baseline (mode ``direct``)."""
        return getattr(self.bundle, "direct", None) is not None

    def supports(self, mode: Mode | str) -> bool:
        """Whether this model runs ``mode``: direct needs the baseline, residual a calibrated weight,
        detail the simulated folds (auto: the mode it was calibrated to run)."""
        mode = Mode(mode)
        mode = Mode(self.bundle.auto_mode) if mode is Mode.AUTO else mode
        return {
            Mode.DIRECT: self.has_direct,
            Mode.RESIDUAL: self.bundle.has_residual,
            Mode.DETAIL: self.bundle.folds is not None,
            Mode.SAMPLE: self.bundle.sampler is not None,
        }.get(mode, True)

    @property
    def window(self) -> int:
        return self.bundle.codespace.config.window

    def resolve(self, settings: RunSettings | None = None, **changes) -> ResolvedRun:
        """The run ``settings`` (default: the animator's, :attr:`settings`) with keyword ``changes``
        (:class:`~.run_settings.RunSettings`' fields) resolved against this model, its body made
        ready (:meth:`body`): what :meth:`animate` runs with them."""
        asked = run_settings(self.settings if settings is None else settings, changes)
        return asked.resolve(self.bundle, self.body(asked.body, allow_outside=asked.allow_outside))

    def body(
        self,
        body: CharacterBody | BodyRecord | str | Path | None = None,
        *,
        allow_outside: bool = False,
        name: str | None = None,
    ) -> CharacterBody:
        """A body to animate on (:mod:`.character_body`): a body.json or character file's path, a
        :class:`~hrr_garment.body.body_file.BodyRecord`, or None for the model's own; refused
        (:class:`~.character_body.BodyOutsideRange`) when it is unlike the model's training bodies, unless
        ``allow_outside``."""
        if body is None and name is None and not allow_outside:
            if self._default_body is None:
                self._default_body = character_body(self.bundle)
            return self._default_body
        return character_body(self.bundle, body, allow_outside=allow_outside, name=name)

    def animate(
        self,
        motion: Motion | str | Path,
        settings: RunSettings | None = None,
        *,
        observe: Observer | None = None,
        **changes,
    ) -> Animation:
        """Animate a whole clip (see :mod:`hrr_garment.inference`) as ``settings`` ask
        (:class:`~.run_settings.RunSettings`; default: the animator's, the model's calibrated mode,
        push-out on, offline, on the model's own body), with keyword ``changes`` to them
        (``animate(motion, mode="regression", push_out=False, body="hero.json")``). A clip on the
        canonical skeleton is played by the run's body (:meth:`body`); ``exclude_sequence`` keeps one
        database sequence out of retrieval (evaluation). The frame path: :mod:`.clip_path`, each
        stage's output shown to ``observe`` where given (evaluation: the cloth before the push-out).
        ``motion`` may be a motion file's path (read by :func:`~hrr_garment.motion.io.load_motion`)."""
        if isinstance(motion, (str, Path)):
            from ..motion.io import load_motion

            motion = load_motion(motion)
        if not isinstance(motion, Motion):
            raise TypeError(f"motion must be a Motion or a motion file's path, not {type(motion).__name__}")
        # again: its arrays are read-only views, but the caller's own arrays under them are not
        motion.validate()
        run = self.resolve(settings, **changes)
        with flush_denormals():
            return animate_clip(FramePath(self, run, observe), run.body.play(motion))

    def features(
        self, motion: Motion, causal: bool = False, body: CharacterBody | None = None, material=None
    ) -> np.ndarray:
        """The model's per-frame motion features (T, F) of a clip (stage 1,
        :func:`~.clip_path.clip_features`): offline or as a stream sees them (``causal``), for ``body``
        (default: the model's own) in ``material`` (default: the model's cloth)."""
        cloth = material_columns(self.bundle, run_material(self.bundle, material))
        return clip_features(self.bundle, motion, (body or self.body()).vector, cloth=cloth, causal=causal)

    def stream(self, settings: RunSettings | None = None, *, rig=None, **changes) -> AnimationStream:
        """One character, causal, one pose in and one frame out (:class:`~.character_stream.AnimationStream`);
        ``settings`` and keyword ``changes`` as :meth:`animate` (a stream is causal whatever they
        say; its settings, its body included, hold for its life); ``rig``: a
        :class:`~hrr_garment.motion.stream_rig.StreamRig` for poses on a source skeleton."""
        return AnimationStream(self, self._stream_run(settings, changes), rig=rig)

    def crowd(self, settings: RunSettings | None = None, *, rig=None, **changes):
        """Many characters, one call per frame for all of them (:class:`~.stream.CrowdStream`);
        arguments as :meth:`stream` (every character of the crowd has the run's body). The run's
        ``device``: "native" (the CPU kernels: every mode, a body per character), a torch device such
        as "cuda" (the regression as one torch step there: :class:`~.torch_crowd.DeviceCrowd`), or
        None: CUDA for a regression crowd whose swing runs as predicted (the torch step runs no
        swing gain) where torch sees a GPU, else native."""
        run = self._stream_run(settings, changes)
        device = run.device
        if device is None:
            as_predicted = run.mode is Mode.REGRESSION and run.swing == 1.0
            device = "cuda" if as_predicted and rig is None and torch.cuda.is_available() else "native"
        run = dataclasses.replace(run, device=device)
        if device == "native":
            return CrowdStream(self, run, rig=rig)
        if rig is not None:
            raise ValueError(
                "a crowd on a torch device takes poses on the canonical skeleton (no rig); "
                "use device='native'"
            )
        from .torch_crowd import DeviceCrowd

        return DeviceCrowd(self, run)

    def _stream_run(self, settings: RunSettings | None, changes: dict) -> ResolvedRun:
        run = self.resolve(settings, **{**changes, "causal": True})
        if run.mode not in CODE_MODES:
            raise ValueError(f"streaming runs auto or one of {', '.join(CODE_MODES)}, not {run.mode.value!r}")
        return run
