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

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from ..artifacts.bundle import Bundle, BundleError, load_bundle
from ..body.capsules import DEFAULT_BODY
from ..errors import InputError, MotionError
from ..garment.smoothing import mean_operator
from ..models.native_codes import native_window_codes
from ..motion.features import causal_features, motion_features
from ..motion.frame import world_vertices
from ..motion.memory import with_memory
from ..motion.motion import Motion
from ..motion.windows import causal_windows, sequence_windows
from ..paths import workspace
from .blending import blend_windows, causal_latents
from .collision import EdgeLimits, PushOutReport, push_out
from .decoding import body_frame_vertices, flush_denormals
from .detail import add_folds
from .fold_track import causal_proposals, offline_proposals, track_folds
from .gate import choose_windows
from .modes import Mode
from .stream import AnimationStream, CrowdStream

MAX_REACH_M = 1.5  # metres from the nearest body joint a garment vertex may be (a long dress's hem: under 0.6)


@dataclass
class Animation:
    """An animated garment: world-space vertices (T, V, 3) at ``fps``, Y up, metres."""

    vertices: np.ndarray
    faces: np.ndarray
    fps: float
    mode: np.ndarray  # (T,) uint8, 1 = retrieval
    entropy: np.ndarray  # (T,) float32
    source: np.ndarray  # (T, 2) int32 retrieved (database sequence, frame) or -1
    joints: np.ndarray  # (T, 22, 3) body joint positions
    garment: str
    model_hash: str
    source_motion: str
    settings: dict = field(default_factory=dict)
    penetration: PushOutReport | None = None
    capsules: np.ndarray | None = None  # (T, C, 2, 3) collision capsule ends, for previews and exports
    doubt: np.ndarray | None = None  # (T,) the gate signal's value per frame (retrieval where below tau)

    @property
    def retrieval_usage(self) -> float:
        return float(self.mode.mean()) if len(self.mode) else 0.0

    def check(self, target: str | Path) -> None:
        """Refuse to hand on an absurd result: non-finite vertices or joints, or a garment vertex
        farther than ``MAX_REACH_M`` from every joint (a damaged or mismatched model, not cloth)."""
        for name, values in (("vertices", self.vertices), ("joints", self.joints)):
            bad = ~np.isfinite(values.reshape(len(values), -1)).all(1)
            if bad.any():
                raise InputError(target, f"the model produced non-finite {name} on {int(bad.sum())} frame(s), first at "
                                         f"frame {int(np.argmax(bad))}; nothing written (is the model bundle damaged?)")
        for t in range(0, len(self.vertices), 256):  # nearest joint of every vertex, a block of frames at a time
            v, j = self.vertices[t:t + 256], self.joints[t:t + 256]
            reach = np.sqrt(((v[:, :, None] - j[:, None]) ** 2).sum(-1).min(-1)).max(1)
            if (reach > MAX_REACH_M).any():
                frame = t + int(np.argmax(reach > MAX_REACH_M))
                raise InputError(target, f"the model put a garment vertex {reach.max():.2f} m from the body at frame {frame} "
                                         f"(more than {MAX_REACH_M:g} m); nothing written (a damaged or mismatched model?)")

    def save(self, path: str | Path) -> Path:
        """Write ``out.h5`` (see :mod:`hrr_garment.data.animation_file`), atomically, after :meth:`check`."""
        from ..data.animation_file import write_animation_h5

        self.check(path)
        return write_animation_h5(path, vertices=self.vertices, faces=self.faces, joints=self.joints, mode=self.mode,
                                  entropy=self.entropy, source=self.source, capsules=self.capsules,
                                  radii=None if self.capsules is None else DEFAULT_BODY.radii,
                                  attrs={"fps": self.fps, "garment": self.garment, "source_motion": self.source_motion,
                                         "model_hash": self.model_hash, **{k: v for k, v in self.settings.items()}})


def find_model(name_or_dir: str | Path) -> Path:
    """A model directory: the path itself, or hrr_work/models/NAME-full, else NAME-quick."""
    path = Path(name_or_dir)
    if (path / "bundle.json").is_file() or path.is_dir():
        return path
    tried = [workspace() / "models" / f"{name_or_dir}-{preset}" for preset in ("full", "quick")]
    for candidate in tried:
        if (candidate / "bundle.json").is_file():
            return candidate
    raise BundleError(name_or_dir, "no trained model: looked for " + ", ".join(str(t) for t in tried)
                      + f" (train one with: hrr-train --garment {name_or_dir})")


class Animator:
    """A loaded model bundle that animates its garment from body motion."""

    def __init__(self, bundle: Bundle, blend: int = 6, precision: str = "float32"):
        """``precision``: the mesh decoder's arithmetic for batches of frames, ``"float32"`` or
        ``"bfloat16"`` (AMX on recent Intel Xeons: about 3x faster for crowds and offline animation;
        :class:`~hrr_garment.models.fast_decoder.FastDecoder`)."""
        self.bundle = bundle
        self.blend = blend  # inertialization frames in causal mode
        self.decoder = bundle.autoencoder.fast_decoder(precision=precision)
        self.smoothing = mean_operator(bundle.template.faces, bundle.template.num_vertices)  # for the push-out
        self.edge_limits = EdgeLimits.of(bundle.template.faces, bundle.template.vertices)  # for the push-out's strain limit
        self._causal_steps: dict[bool, object] = {}

    def causal_step(self, regression: bool):
        """The window step (:class:`~hrr_garment.models.codes.WindowCodes`' function) that causal inference runs,
        offline and streaming alike, so both compute the same bits: the native kernel
        (:mod:`hrr_garment.models.native_codes`), or None where it is unavailable (each path then
        uses its PyTorch form)."""
        if regression not in self._causal_steps:
            self._causal_steps[regression] = native_window_codes(self.bundle.codespace, regression, last_frame=True)
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
        detail the simulated folds."""
        mode = self.resolve_mode(mode)
        return {Mode.DIRECT: self.has_direct, Mode.RESIDUAL: self.bundle.has_residual,
                Mode.DETAIL: self.bundle.folds is not None}.get(mode, True)

    @property
    def window(self) -> int:
        return self.bundle.codespace.config.window

    def animate(self, motion: Motion, mode: Mode | str = Mode.AUTO, tau: float | None = None, collision: bool = True,
                causal: bool = False, exclude_sequence: int | None = None, gate: str | None = None,
                detail_base: str | None = None, detail_strength: float | None = None) -> Animation:
        """Animate a whole clip (see :mod:`hrr_garment.inference`): ``mode`` auto (the model's calibrated
        choice, :meth:`resolve_mode`) | hybrid | regression | retrieval | residual | detail | naive-nn,
        or direct (the baseline, when the bundle has it; offline only); ``gate`` the hybrid's signal
        (default the model's calibrated one, :data:`~hrr_garment.artifacts.gate_signals.GATE_SIGNALS`) and
        ``tau`` its threshold (default the one calibrated for that signal); ``causal`` gives what
        streaming gives; ``exclude_sequence`` keeps one database sequence out of retrieval (evaluation);
        ``detail_base`` ("regression" or "residual") and ``detail_strength`` (in (0, 2], 1: the
        folds as simulated) the detail mode's look (default the model's calibrated one)."""
        mode = self.resolve_mode(mode, gate, tau, detail_base is not None or detail_strength is not None)
        gate, tau = self.gate_setting(gate, tau)
        detail = self.bundle.detail_setting(detail_base, detail_strength) if mode is Mode.DETAIL else None
        with flush_denormals():
            return self._animate(motion, mode, tau, collision, causal, exclude_sequence, gate, detail)

    def resolve_mode(self, mode: Mode | str, gate: str | None = None, tau: float | None = None,
                     detail: bool = False) -> Mode:
        """``mode`` itself, or for ``auto`` the mode this model was calibrated to run
        (:attr:`~hrr_garment.artifacts.bundle.Bundle.auto_mode`); an explicit ``gate`` or ``tau`` is
        the hybrid's setting, so with either auto runs the hybrid, and a detail setting (``detail``:
        one was given) the detail mode's. A ValueError where the settings ask for two modes or a
        named mode does not use them."""
        mode = Mode(mode)
        hybrid = gate is not None or tau is not None
        if detail and mode not in (Mode.AUTO, Mode.DETAIL):
            raise ValueError(f"a detail base or strength sets the detail mode; mode {mode.value} does not use them")
        if mode is not Mode.AUTO:
            return mode
        if hybrid and detail:
            raise ValueError("a gate or tau sets the hybrid and a detail base or strength the detail mode: name the mode")
        return Mode.HYBRID if hybrid else Mode.DETAIL if detail else Mode(self.bundle.auto_mode)

    def gate_setting(self, gate: str | None, tau: float | None) -> tuple[str, float]:
        """The gate signal and threshold to run: the model's calibrated ones unless given."""
        gate = self.bundle.gate if gate is None else str(gate)
        return gate, self.bundle.gate_tau(gate) if tau is None else float(tau)

    def _animate(self, motion: Motion, mode: str, tau: float, collision: bool, causal: bool,
                 exclude_sequence: int | None, gate: str, detail: tuple[str, float] | None) -> Animation:
        t_frames, w = motion.num_frames, self.window
        if t_frames < 1:
            raise MotionError(motion.source, "the motion has no frames")
        if mode is Mode.DETAIL:
            self.bundle.require_folds()
        if mode == Mode.DIRECT:
            latents, proposals = self._direct_latents(motion), None
            retrieved, entropy = np.zeros(t_frames, np.uint8), np.full(t_frames, np.nan, np.float32)
            source, doubt = np.full((t_frames, 2), -1, np.int32), entropy.copy()
        else:
            if causal:
                feats = causal_windows(self.features(motion, causal=True), w)
                choice = self._choose(feats, mode, tau, exclude_sequence, gate, detail, last_frame=True)
                latents = causal_latents(choice, self.blend)
                proposals = causal_proposals(choice.source, w) if choice.detail else None
                per_frame = np.arange(t_frames)
            else:
                feats = self.features(motion)
                if t_frames < w:  # shorter than one window: pad with the last frame, keep the first T outputs
                    feats = np.concatenate([feats, np.repeat(feats[-1:], w - t_frames, 0)])
                windows = np.ascontiguousarray(sequence_windows(feats, w))
                choice = self._choose(windows, mode, tau, exclude_sequence, gate, detail)
                latents = blend_windows(choice.latents, len(feats))[:t_frames]
                proposals = offline_proposals(choice.source, t_frames, w) if choice.detail else None
                per_frame = np.clip(np.arange(t_frames) - w // 2, 0, len(windows) - 1)  # the window centred on t
            retrieved, entropy = choice.retrieved[per_frame].astype(np.uint8), choice.entropy[per_frame].astype(np.float32)
            source, doubt = choice.source[per_frame], choice.doubt[per_frame].astype(np.float32)
        local = body_frame_vertices(self.bundle, latents, self.decoder)
        if proposals is not None:  # the detail mode: simulated folds on the regression's shape (or the residual's)
            store = self.bundle.folds
            rows, weights = track_folds(proposals, store.offsets)
            local = add_folds(local, store.folds(rows, weights), self.smoothing, store.passes, detail[1])
        vertices = world_vertices(local, motion)
        report = None
        if collision:
            vertices, report = push_out(vertices, motion, self.bundle.template.faces, mean=self.smoothing,
                                        limits=self.edge_limits)
        return Animation(vertices, self.bundle.template.faces, motion.fps, retrieved, entropy, source, motion.joint_positions,
                         self.bundle.garment, self.bundle.content_hash, motion.source,
                         {"mode": str(mode), "gate": gate, "tau": tau, "causal": int(causal), "collision": int(collision),
                          **({"detail_base": detail[0], "detail_strength": detail[1]} if detail else {})},
                         report, np.stack(DEFAULT_BODY.pose_motion(motion), 2).astype(np.float32), doubt)

    def _direct_latents(self, motion: Motion) -> np.ndarray:
        """(T, nodes, C) latents of the direct-regression baseline (causal: a GRU over the clip)."""
        if self.bundle.direct is None:
            raise InputError(self.bundle.folder, "has no direct-regression baseline: train it with hrr-train --stage baseline")
        feats = self.features(motion)
        with torch.no_grad():
            z = self.bundle.direct(torch.from_numpy(self.bundle.motion_stats.normalize(feats).astype(np.float32))[None])[0]
        return self.bundle.latent_stats.denormalize(z.numpy()).reshape(len(feats), *self.bundle.autoencoder.latent_shape)

    def features(self, motion: Motion, causal: bool = False) -> np.ndarray:
        """The model's per-frame motion features (T, F) of a clip: the plain ones, offline or as a
        stream sees them (``causal``), with the motion memory the model was trained with."""
        plain = causal_features(motion) if causal or motion.num_frames < 2 else motion_features(motion)  # one frame: no velocity
        return with_memory(plain, motion.fps, self.bundle.codespace.config.memory)

    def _choose(self, windows: np.ndarray, mode: str, tau: float, exclude_sequence: int | None, gate: str,
                detail: tuple[str, float] | None = None, last_frame: bool = False):
        exclude = None if exclude_sequence is None else np.full(len(windows), exclude_sequence)
        step = self.causal_step(Mode(mode).regresses) if last_frame else None
        return choose_windows(self.bundle, windows, mode, tau, exclude, last_frame, step=step, gate=gate,
                              detail_base=detail[0] if detail else "regression")

    def stream(self, mode: Mode | str = Mode.AUTO, tau: float | None = None, collision: bool = True,
               rig=None, gate: str | None = None, detail_base: str | None = None,
               detail_strength: float | None = None) -> AnimationStream:
        """One character, causal, one pose in and one frame out (:class:`~.stream.AnimationStream`);
        ``rig``: a :class:`~hrr_garment.motion.stream_rig.StreamRig` for poses on a source skeleton;
        ``gate``, ``tau``, ``detail_base``, ``detail_strength``: as :meth:`animate`."""
        return AnimationStream(self, mode, tau, collision, rig, gate, detail_base, detail_strength)

    def crowd(self, mode: Mode | str = Mode.AUTO, tau: float | None = None, collision: bool = True,
              rig=None, gate: str | None = None, detail_base: str | None = None,
              detail_strength: float | None = None) -> CrowdStream:
        """Many characters, one call per frame for all of them (:class:`~.stream.CrowdStream`)."""
        return CrowdStream(self, mode, tau, collision, rig, gate, detail_base, detail_strength)
