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
from functools import partial
from pathlib import Path

import numpy as np
import torch

from ..artifacts.bundle import Bundle, BundleError, load_bundle
from ..body.body_file import BodyRecord
from ..body.measures import with_body
from ..errors import InputError, MotionError
from ..garment.smoothing import mean_operator
from ..models.native_codes import native_window_codes
from ..motion.features import causal_features, motion_features
from ..motion.frame import world_vertices
from ..motion.memory import with_memory
from ..motion.motion import Motion
from ..motion.windows import causal_windows, sequence_windows
from ..paths import workspace
from . import collision
from .animation import Animation
from .blending import blend_windows, causal_latents
from .bodies import CharacterBody, character_body
from .character_stream import AnimationStream
from .collision import PushOutSettings, push_out
from .decoding import body_frame_vertices, flush_denormals
from .detail import add_folds
from .edge_limits import EdgeLimits
from .fold_track import causal_proposals, follow_over_time, offline_proposals, track_folds
from .gate import WindowChoice, choose_windows, frame_gates
from .modes import CODE_MODES, Mode
from .run_settings import ResolvedRun, RunSettings, run_settings
from .stream import CrowdStream
from .subspace_push import SubspacePush
from .swing import SwingGain


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
    """A loaded model bundle that animates its garment from body motion."""

    def __init__(self, bundle: Bundle, blend: int = 6, precision: str = "float32"):
        """``precision``: the mesh decoder's arithmetic for batches of frames, ``"float32"`` or
        ``"bfloat16"`` (AMX on recent Intel Xeons: about 3x faster for crowds and offline animation;
        :class:`~hrr_garment.models.fast_decoder.FastDecoder`)."""
        self.bundle = bundle
        self.blend = blend  # inertialization frames in causal mode
        self.decoder = bundle.autoencoder.fast_decoder(precision=precision)  # the full mesh decoder
        self.smoothing = mean_operator(
            bundle.template.faces, bundle.template.num_vertices
        )  # for the push-out
        self.edge_limits = EdgeLimits.of(
            bundle.template.faces, bundle.template.vertices, mean=self.smoothing
        )  # the push-out's
        self._causal_steps: dict[bool, object] = {}
        self._default_body: CharacterBody | None = None
        self._subspace_push: SubspacePush | None = None

    @property
    def subspace_push(self) -> SubspacePush | None:
        """The push in the bundle's fast-decoder subspace (:mod:`.subspace_push`), made once; None without a fast decoder."""
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
        """The mesh decoder ``run`` asks for: the full one (:attr:`decoder`) or the bundle's fast
        subspace decoder (:mod:`hrr_garment.models.subspace`); both take (B, N, C) latents to (B, V, 3)."""
        return self.bundle.subspace if run.decoder == "fast" else self.decoder

    def causal_step(self, regression: bool):
        """The window step (:class:`~hrr_garment.models.codes.WindowCodes`' function) that causal inference runs,
        offline and streaming alike, so both compute the same bits: the native kernel
        (:mod:`hrr_garment.models.native_codes`), or None where it is unavailable (each path then
        uses its PyTorch form)."""
        if regression not in self._causal_steps:
            self._causal_steps[regression] = native_window_codes(
                self.bundle.codespace, regression, last_frame=True
            )
        return self._causal_steps[regression]

    @classmethod
    def load(cls, model: str | Path, precision: str = "float32") -> "Animator":
        return cls(load_bundle(find_model(model), workspace() / "cache"), precision=precision)

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
        }.get(mode, True)

    @property
    def window(self) -> int:
        return self.bundle.codespace.config.window

    def resolve(self, settings: RunSettings | None = None, **changes) -> ResolvedRun:
        """The run ``settings`` (with keyword ``changes``: :class:`~.run_settings.RunSettings`'
        fields) resolved against this model: what :meth:`animate` runs with them."""
        return run_settings(settings, changes).resolve(self.bundle)

    def body(
        self,
        body: CharacterBody | BodyRecord | str | Path | None = None,
        *,
        allow_outside: bool = False,
        name: str | None = None,
    ) -> CharacterBody:
        """A body to animate on (:mod:`.bodies`): a body.json or character file's path, a
        :class:`~hrr_garment.body.body_file.BodyRecord`, or None for the model's own; refused
        (:class:`~.bodies.BodyOutsideRange`) when it is unlike the model's training bodies, unless
        ``allow_outside``."""
        if body is None and name is None and not allow_outside:
            if self._default_body is None:
                self._default_body = character_body(self.bundle)
            return self._default_body
        return character_body(self.bundle, body, allow_outside=allow_outside, name=name)

    def animate(
        self,
        motion: Motion,
        settings: RunSettings | None = None,
        *,
        body=None,
        allow_outside: bool = False,
        exclude_sequence: int | None = None,
        **changes,
    ) -> Animation:
        """Animate a whole clip (see :mod:`hrr_garment.inference`) as ``settings`` ask
        (:class:`~.run_settings.RunSettings`; default: the model's calibrated mode, push-out on,
        offline), with keyword ``changes`` to them (``animate(motion, mode="regression",
        collision=False)``), on ``body`` (:meth:`body`; default the model's own: the mannequin,
        or the one body it was trained on). A clip on the canonical skeleton is played by the
        body. ``exclude_sequence`` keeps one database sequence out of retrieval (evaluation)."""
        motion.validate()  # again: its arrays are read-only views, but the caller's own arrays under them are not
        run = self.resolve(settings, **changes)
        character = self.body(body, allow_outside=allow_outside)
        if exclude_sequence is not None:
            exclude_sequence = self._database_sequence(exclude_sequence)
        with flush_denormals():
            return self._animate(character.play(motion), run, exclude_sequence, character)

    def _database_sequence(self, index: object) -> int:
        """``index`` as a database sequence index; a ValueError naming the range otherwise."""
        if isinstance(index, np.integer):
            index = int(index)
        count = len(self.bundle.database.names)
        if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < count:
            raise ValueError(
                f"exclude_sequence must be a database sequence index in 0..{count - 1}, got {index!r}"
            )
        return index

    def _animate(
        self, motion: Motion, run: ResolvedRun, exclude_sequence: int | None, character: CharacterBody
    ) -> Animation:
        t_frames, w = motion.num_frames, self.window
        if t_frames < 1:
            raise MotionError(motion.source, "the motion has no frames")
        regression = (
            None  # the latents' share that swings as the regression (gate.WindowChoice.regression_part)
        )
        if run.mode == Mode.DIRECT:
            latents, proposals = self._direct_latents(motion, character), None
            retrieved, entropy = np.zeros(t_frames, np.uint8), np.full(t_frames, np.nan, np.float32)
            match, doubt = np.full((t_frames, 2), -1, np.int32), entropy.copy()
        else:
            if run.causal:
                frames = self.features(motion, causal=True, body=character)
                gates = frame_gates(self.bundle, self.causal_step(run.mode.regresses), frames)
                if gates is not None:  # each frame's once, not in each of the W windows that hold it
                    gates = causal_windows(gates, w, view=True)
                choice = self._choose(
                    causal_windows(frames, w), run, exclude_sequence, last_frame=True, gates=gates
                )
                latents = causal_latents(choice, self.blend)
                regression = None if choice.regression_part is None else choice.regression_part[:, -1]
                proposals = causal_proposals(choice.match, w) if choice.lends_folds else None
                per_frame = np.arange(t_frames)
            else:
                feats = self.features(motion, body=character)
                if t_frames < w:  # shorter than one window: pad with the last frame, keep the first T outputs
                    feats = np.concatenate([feats, np.repeat(feats[-1:], w - t_frames, 0)])
                windows = np.ascontiguousarray(sequence_windows(feats, w))
                choice = self._choose(windows, run, exclude_sequence)
                latents = blend_windows(choice.latents, len(feats))[:t_frames]
                regression = (
                    None
                    if choice.regression_part is None
                    else blend_windows(choice.regression_part, len(feats))[:t_frames]
                )
                proposals = offline_proposals(choice.match, t_frames, w) if choice.lends_folds else None
                per_frame = np.clip(
                    np.arange(t_frames) - w // 2, 0, len(windows) - 1
                )  # the window centred on t
            retrieved, entropy = (
                choice.retrieved[per_frame].astype(np.uint8),
                choice.entropy[per_frame].astype(np.float32),
            )
            match, doubt = choice.match[per_frame], choice.doubt[per_frame].astype(np.float32)
        if run.swing != 1.0:  # the free cloth's swing restored (causal: offline, streams and crowds alike)
            latents = SwingGain.of(run.swing, self.bundle.node_hang_m, motion.fps).apply(latents, regression)
        local = body_frame_vertices(self.bundle, latents, self.decoder_for(run))
        if (
            proposals is not None
        ):  # the detail mode: simulated folds on the regression's shape (or the residual's)
            store = self.bundle.folds
            rows, weights = track_folds(proposals, store.offsets)
            local = add_folds(
                local,
                store.folds(rows, weights),
                self.smoothing,
                passes=store.passes,
                strength=run.detail.strength,
                limits=self.edge_limits,
                follow=partial(follow_over_time, mean=self.smoothing),
                weights=self.bundle.fold_weights,
            )
        vertices = world_vertices(local + character.offset, motion)  # stood on the body's own rest shape
        report = None
        if run.collision:
            vertices, report = push_out(
                vertices,
                motion,
                self.bundle.template.faces,
                body=character.body,
                mean=self.smoothing,
                limits=self.edge_limits,
                settings=self.push_settings(run),
            )
        return Animation(
            vertices=vertices,
            faces=self.bundle.template.faces,
            fps=motion.fps,
            retrieved=retrieved,
            entropy=entropy,
            match=match,
            joints=motion.joint_positions,
            garment=self.bundle.garment,
            model_hash=self.bundle.content_hash,
            motion_file=motion.source,
            settings=run.record(),
            penetration=report,
            capsules=np.stack(character.body.pose_motion(motion), 2).astype(np.float32),
            radii=character.body.radii,
            body=character.name,
            skeleton=motion,
            body_record=character.record,
            doubt=doubt,
        )

    def _direct_latents(self, motion: Motion, character: CharacterBody) -> np.ndarray:
        """(T, nodes, C) latents of the direct-regression baseline (causal: a GRU over the clip)."""
        if self.bundle.direct is None:
            raise InputError(
                self.bundle.folder,
                "has no direct-regression baseline: train it with hrr-train --stage baseline",
            )
        feats = self.features(motion, body=character)
        with torch.no_grad():
            z = self.bundle.direct(
                torch.from_numpy(self.bundle.motion_stats.normalize(feats).astype(np.float32))[None]
            )[0]
        return self.bundle.latent_stats.denormalize(z.numpy()).reshape(
            len(feats), *self.bundle.autoencoder.latent_shape
        )

    def features(self, motion: Motion, causal: bool = False, body: CharacterBody | None = None) -> np.ndarray:
        """The model's per-frame motion features (T, F) of a clip: the plain ones, offline or as a
        stream sees them (``causal``), with the motion memory the model was trained with and, for
        a model trained across bodies, the measures of ``body`` (default: the model's own)."""
        plain = (
            causal_features(motion) if causal or motion.num_frames < 2 else motion_features(motion)
        )  # one frame: no velocity
        feats = with_memory(plain, motion.fps, self.bundle.codespace.config.memory)
        if self.bundle.codespace.config.body_features:
            feats = with_body(feats, (body or self.body()).vector)
        return feats

    def _choose(
        self,
        windows: np.ndarray,
        run: ResolvedRun,
        exclude_sequence: int | None = None,
        last_frame: bool = False,
        gates: np.ndarray | None = None,
    ) -> WindowChoice:
        exclude = None if exclude_sequence is None else np.full(len(windows), exclude_sequence)
        step = self.causal_step(run.mode.regresses) if last_frame else None
        return choose_windows(
            self.bundle, windows, run, exclude=exclude, last_frame=last_frame, step=step, gates=gates
        )

    def stream(
        self,
        settings: RunSettings | None = None,
        *,
        rig=None,
        body=None,
        allow_outside: bool = False,
        **changes,
    ) -> AnimationStream:
        """One character, causal, one pose in and one frame out (:class:`~.character_stream.AnimationStream`);
        ``settings`` and keyword ``changes`` as :meth:`animate` (a stream is causal whatever they
        say; its settings hold for its life); ``rig``: a
        :class:`~hrr_garment.motion.stream_rig.StreamRig` for poses on a source skeleton;
        ``body``: the character's body, as :meth:`animate` takes it."""
        return AnimationStream(
            self,
            self._stream_run(settings, changes),
            rig=rig,
            body=self.body(body, allow_outside=allow_outside),
        )

    def crowd(
        self,
        settings: RunSettings | None = None,
        *,
        rig=None,
        body=None,
        allow_outside: bool = False,
        device: str | None = None,
        **changes,
    ):
        """Many characters, one call per frame for all of them (:class:`~.stream.CrowdStream`);
        arguments as :meth:`stream` (every character of the crowd has ``body``). ``device``:
        "native" (the CPU kernels: every mode, a body per character), a torch device such as
        "cuda" (the regression as one torch step there: :class:`~.torch_crowd.DeviceCrowd`), or
        None: CUDA for a regression crowd where torch sees a GPU, else native."""
        run = self._stream_run(settings, changes)
        if device is None:
            device = (
                "cuda"
                if run.mode is Mode.REGRESSION and rig is None and torch.cuda.is_available()
                else "native"
            )
        character = self.body(body, allow_outside=allow_outside)
        if device == "native":
            return CrowdStream(self, run, rig=rig, body=character)
        if rig is not None:
            raise ValueError(
                "a crowd on a torch device takes poses on the canonical skeleton (no rig); use device='native'"
            )
        from .torch_crowd import DeviceCrowd

        return DeviceCrowd(self, run, device=device, body=character)

    def _stream_run(self, settings: RunSettings | None, changes: dict) -> ResolvedRun:
        run = self.resolve(settings, **{**changes, "causal": True})
        if run.mode not in CODE_MODES:
            raise ValueError(f"streaming runs auto or one of {', '.join(CODE_MODES)}, not {run.mode.value!r}")
        return run
