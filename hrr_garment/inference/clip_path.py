"""A whole clip through the frame path (:mod:`.frame_path`), stage by stage: what
:meth:`~.animator.Animator.animate` runs, offline (every window that holds a frame of the clip, its
ends repeated, blended) or causal (each
frame from the window ending at it, as a stream sees the clip; a stream's frame t equals it)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from ..errors import InputError, MotionError
from ..motion.features import causal_features, motion_features
from ..motion.memory import with_memory
from ..motion.motion import Motion
from ..motion.windows import causal_windows, covering_windows
from .animation import Animation
from .blending import blend_windows, causal_latents
from .decoding import body_frame_vertices
from .fold_track import causal_proposals, centred_windows, offline_proposals, track_folds
from .frame_path import FramePath, with_conditions
from .gate import frame_gates
from .modes import Mode


def clip_features(
    bundle, motion: Motion, measures: np.ndarray, cloth: np.ndarray | None = None, causal: bool = False
) -> np.ndarray:
    """Stage 1 over a clip: the model's per-frame features (T, F): the plain ones, offline or as a
    stream sees them (``causal``), with the motion memory the model was trained with and, for a
    model across bodies, the body's ``measures``, for a model across cloths the ``cloth``'s values."""
    plain = (
        causal_features(motion) if causal or motion.num_frames < 2 else motion_features(motion)
    )  # one frame: no velocity
    memory = with_memory(plain, motion.fps, bundle.codespace.config.memory)
    return with_conditions(bundle, memory, measures, cloth=cloth)


@dataclass
class ClipLatents:
    """Stages 1 to 4 over a clip: each frame's latents and what the window that chose them says."""

    latents: np.ndarray  # (T, nodes, C)
    regression: np.ndarray | None  # (T, nodes, C) their share that swings as the regression, None: all
    proposals: np.ndarray | None  # the detail mode's fold proposals (fold_track), None outside it
    retrieved: np.ndarray  # (T,) uint8
    entropy: np.ndarray  # (T,) float32
    match: np.ndarray  # (T, 2) int32
    doubt: np.ndarray  # (T,) float32
    features: np.ndarray  # (T, F) each frame's features (stage 1; the settling lag reads them)
    # (T, nodes, C) the regression's own latents, which the mode's additions depart from (the
    # push-out takes them back where they go into the body: .take_back); None: none to take back
    base: np.ndarray | None = None


def clip_latents(path: FramePath, motion: Motion) -> ClipLatents:
    """Stages 1 (features), 2 (windows), 3 (choice) and 4 (blending) over a clip, as the run asks."""
    if path.run.mode == Mode.DIRECT:
        return _direct(path, motion)
    t_frames, w, bundle = motion.num_frames, path.window, path.bundle
    features = path.seen(
        "features", clip_features(bundle, motion, path.run.body.vector, path.cloth, causal=path.run.causal)
    )
    if path.run.causal:
        gates = frame_gates(bundle, path.step, features)
        if gates is not None:  # each frame's once, not in each of the W windows that hold it
            gates = causal_windows(gates, w, view=True)
        choice = path.choose(path.seen("windows", causal_windows(features, w)), last_frame=True, gates=gates)
        latents = causal_latents(choice, path.blend)
        if path.run.mode is Mode.SAMPLE:  # the draw departs from the regression, frame after frame
            latents = path.draw(features, latents)
        regression = None if choice.regression_part is None else choice.regression_part[:, -1]
        base = None if choice.regression is None or not path.takes_back else choice.regression[:, -1]
        proposals = causal_proposals(choice.match, w) if choice.lends_folds else None
        per_frame = np.arange(t_frames)
    else:
        windows = path.seen("windows", np.ascontiguousarray(covering_windows(features, w)))
        choice = path.choose(windows)
        clip = slice(w - 1, w - 1 + t_frames)  # the blend's frames of the clip (its ends padded)
        latents = blend_windows(choice.latents, len(windows) + w - 1)[clip]
        regression = (
            None
            if choice.regression_part is None
            else blend_windows(choice.regression_part, len(windows) + w - 1)[clip]
        )
        base = None
        if choice.regression is not None and path.takes_back:
            base = blend_windows(choice.regression, len(windows) + w - 1)[clip]
        proposals = offline_proposals(choice.match, t_frames, w) if choice.lends_folds else None
        per_frame = centred_windows(t_frames, w)  # the window centred on t
    return ClipLatents(
        path.seen("blending", latents),
        regression,
        proposals,
        choice.retrieved[per_frame].astype(np.uint8),
        choice.entropy[per_frame].astype(np.float32),
        choice.match[per_frame],
        choice.doubt[per_frame].astype(np.float32),
        features[:t_frames],
        base,
    )


def _direct(path: FramePath, motion: Motion) -> ClipLatents:
    """Stages 1 to 4 of the direct-regression baseline: its GRU over the clip's features in place
    of windows, choice and blending."""
    bundle, t_frames = path.bundle, motion.num_frames
    if bundle.direct is None:
        raise InputError(
            bundle.folder, "has no direct-regression baseline: train it with hrr-train --stage direct"
        )
    features = path.seen("features", clip_features(bundle, motion, path.run.body.vector, path.cloth))
    with torch.no_grad():
        z = bundle.direct(torch.from_numpy(bundle.motion_stats.normalize(features).astype(np.float32))[None])[
            0
        ]
    latents = bundle.latent_stats.denormalize(z.numpy()).reshape(
        len(features), *bundle.autoencoder.latent_shape
    )
    entropy = np.full(t_frames, np.nan, np.float32)
    return ClipLatents(
        path.seen("blending", latents),
        None,
        None,
        np.zeros(t_frames, np.uint8),
        entropy,
        np.full((t_frames, 2), -1, np.int32),
        entropy.copy(),
        features,
    )


def animate_clip(path: FramePath, motion: Motion) -> Animation:
    """A clip played by the run's body (:meth:`~.bodies.CharacterBody.play`) through the nine
    stages -> its :class:`~.animation.Animation`."""
    if motion.num_frames < 1:
        raise MotionError(motion.source, "the motion has no frames")
    chosen = clip_latents(path, motion)
    latents, gain = chosen.latents, path.swing_gain(motion.fps)
    if gain is not None:  # the free cloth's swing restored (causal: offline, streams and crowds alike)
        latents = gain.apply(latents, chosen.regression)
    lag = path.settle_lag(motion.fps)
    if lag is not None:  # the cloth settling after a stop (as streams and crowds lag it)
        latents = lag.apply(latents, chosen.features)
    local = path.seen("decoding", body_frame_vertices(path.bundle, path.seen("swing", latents), path.decoder))
    if (
        chosen.proposals is not None
    ):  # the detail mode: simulated folds on the regression's shape (or the residual's)
        store = path.bundle.folds
        rows, weights = track_folds(chosen.proposals, store.offsets)
        local = path.add_folds(local, store.folds(rows, weights), follow=path.follow_over_time)
    path.seen("folds", local)
    character, bundle = path.run.body, path.bundle
    vertices = path.world(local + character.offset, motion)  # stood on the body's own rest shape
    push_body = (
        character.push_body(motion, visible=path.run.push_body == "visible") if path.run.push_out else None
    )
    base = None  # the regression's cloth, where the run adds to it (.take_back)
    if chosen.base is not None:
        stood = body_frame_vertices(bundle, chosen.base, path.decoder) + character.offset
        base = path.world(stood, motion, seen=False)
    vertices, report = path.push_out(vertices, motion, push_body, base=base)
    return Animation(
        vertices=vertices,
        faces=bundle.template.faces,
        fps=motion.fps,
        retrieved=chosen.retrieved,
        entropy=chosen.entropy,
        match=chosen.match,
        joints=motion.joint_positions,
        garment=bundle.garment,
        model_hash=bundle.content_hash,
        motion_file=motion.source,
        settings=path.run.record(),
        penetration=report,
        capsules=np.stack(character.body.pose_motion(motion), 2).astype(np.float32),
        radii=character.body.radii,
        body_name=character.name,
        skeleton=motion,
        body_record=character.record,
        doubt=chosen.doubt,
    )
